"""Records from a running cell: record-cell, diagnose, replay (issue 15, docs/records.md).

A simulated cell (``rheo-shaping cell --namespace /rec``, the simulator's camera on,
every effect off) is recorded by ``rheo-shaping record-cell`` started before it; the
record's camera frames lie on the core's offline centreline within the camera's noise,
``rheo-shaping diagnose`` runs on it and finds no effect (verdict ``none``), and
``rheo-shaping replay`` publishes it back into ROS on its own stamps.
"""
from __future__ import annotations

import json
import os
import subprocess
import time

import numpy as np
import pytest

pytest.importorskip("rclpy")

from rheo_shaping.sheet.effects import nominal  # noqa: E402
from rheo_shaping.records.measurement import nodes_at  # noqa: E402
from rheo_shaping.params.node_params import SimulatorNodeParams  # noqa: E402
from rheo_shaping.nodes import topics as T  # noqa: E402
from rheo_shaping.records.bag import read_record  # noqa: E402
from rheo_shaping.planning.movement import movement_plan, run_movement  # noqa: E402

from _support.ros import BIN, Recorder  # noqa: E402
from _support.cells import base_cell  # noqa: E402

NSPACE = "/rec"
TIMEOUT_S = 300.0


def _cli(*args, **kwargs) -> subprocess.Popen:
    return subprocess.Popen([str(BIN / "rheo-shaping"), *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ), **kwargs)


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Shortest distance [m] of each point (P, 2) to the polyline (K, 2)."""
    a, b = line[:-1][None], line[1:][None]
    p = points[:, None]
    ab = b - a
    s = np.clip(np.sum((p - a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-30), 0, 1)
    return np.min(np.linalg.norm(p - (a + s[..., None] * ab), axis=2), axis=1)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """One simulated cell recorded by record-cell: (record directory, cell's JSON result)."""
    import rclpy
    from rclpy.context import Context
    folder = tmp_path_factory.mktemp("records")
    out = folder / "cell-run"
    # the planner waits for ~/start, which record-cell calls once it receives the cell
    # (so the record holds the state before the start, whatever discovery takes)
    params = folder / "cell.yaml"
    params.write_text("/**/planner:\n  ros__parameters:\n    autostart: false\n")
    recorder = _cli("record-cell", "--namespace", NSPACE, "--out", str(out), "--json",
                    "--timeout", str(TIMEOUT_S), "--start")
    cell = None
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("record_cell_test", context=context)
    from rclpy.executors import SingleThreadedExecutor
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        # the recorder listens before the cell starts (matched-endpoint wait on the graph)
        topic = T.TOOL_COMMAND.in_namespace(NSPACE)
        ok = False
        for _ in range(600):
            if node.count_subscribers(topic) >= 1 or recorder.poll() is not None:
                ok = node.count_subscribers(topic) >= 1
                break
            executor.spin_once(timeout_sec=0.1)
        assert ok, f"record-cell never subscribed to {topic}: {recorder.communicate()}"
        cell = _cli("cell", "--namespace", NSPACE, "--json", "--real-time-factor", "20",
                    "--timeout", str(TIMEOUT_S), "--params", str(params))
        cell_out, cell_err = cell.communicate(timeout=TIMEOUT_S)
        rec_out, rec_err = recorder.communicate(timeout=TIMEOUT_S)
    finally:
        for p in (recorder, cell):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    assert cell.returncode == 0, cell_out + cell_err
    assert recorder.returncode == 0, rec_out + rec_err
    summary = json.loads(rec_out.strip().splitlines()[-1])
    assert summary["record"] == str(out)
    return out, json.loads(cell_out.strip().splitlines()[-1])


def test_record_cell_writes_a_record_of_the_run(recorded):
    out, result = recorded
    cell = base_cell()
    rec = read_record(out)
    assert rec.scenario == nominal(cell)
    assert result["finished"] and not result["aborted"]
    # t = 0 is the process start: the tool is at the plan's start then (the simulator
    # places it at the first set-point), and the record covers the whole process.
    plan = movement_plan(cell)
    assert rec.pose_t[0] == 0.0
    np.testing.assert_allclose(rec.pose_xz[0], plan.position(0.0), atol=1e-9)
    assert rec.duration >= cell.movement.process_time - 0.25
    assert rec.has_wrench
    # camera frames on a 2 Hz grid of process time (each at the first 0.2 s step at or
    # after it; 5 % of frames dropped): consecutive frames 0.4-0.6 s apart, or a multiple
    period = 1.0 / SimulatorNodeParams().camera_rate
    gaps = np.diff(rec.profile_t)
    assert np.all(gaps > 0.3)
    assert len(rec.profiles) >= 0.8 * cell.movement.process_time / period
    # the bag keeps the cell's own stamps (simulated time), never zero
    from rosbags.rosbag2 import Reader
    with Reader(out) as reader:
        stamps = [t for _c, t, _r in reader.messages()]
    assert min(stamps) > 0


def test_record_cell_frames_are_the_sheet_seen_by_the_camera(recorded):
    """Every camera point lies on the core's offline centreline within 5 sigma of the
    camera noise (the closed loop matches the offline run to ~1e-6 m, docs/ros.md)."""
    out, _ = recorded
    cell = base_cell()
    rec = read_record(out)
    run = run_movement(cell)
    sigma = SimulatorNodeParams().camera_noise
    worst = 0.0
    for t, pts in zip(rec.profile_t, rec.profiles):
        d = _distance_to_polyline(pts, nodes_at(run, t))
        worst = max(worst, float(d.max()))
    print(f"largest distance of a camera point to the offline centreline: {worst * 1e3:.3f} mm")
    assert worst < 5 * sigma * np.sqrt(2)


def test_diagnose_a_recorded_cell_finds_no_effect(recorded):
    out, _ = recorded
    # a record of the model itself (the simulator node): its floor is numerics
    proc = subprocess.run([str(BIN / "rheo-shaping"), "diagnose", str(out), "--json",
                           "--quiet", "--floor", "numerics"], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    print(f"diagnose verdict on the recorded cell: {result['verdict']}")
    assert result["verdict"] == "none", result


def test_replay_publishes_the_record_on_its_own_stamps(recorded, ros):
    from rosbags.rosbag2 import Reader
    from rheo_shaping.nodes import messages as m
    from rheo_shaping.nodes.replay import get_message
    out, _ = recorded
    with Reader(out) as reader:
        conns = {c.id: c.topic for c in reader.connections}
        bag = {}
        from rosbags.typesys import Stores, get_typestore
        ts = get_typestore(Stores.ROS2_JAZZY)
        for c, _t, raw in reader.messages():
            msg = ts.deserialize_cdr(raw, c.msgtype)
            s = msg.header.stamp
            bag.setdefault(conns[c.id], []).append(s.sec * 1_000_000_000 + s.nanosec)
        types = {c.topic: c.msgtype for c in reader.connections}
    node = ros.node("replay_listener")
    ns = "/rp"
    # a reader on every topic of the record: the replay's --wait ends when each is matched
    rec = Recorder(node, {ns + topic: get_message(msgtype) for topic, msgtype in types.items()}
                   | {T.NAMESPACED_CLOCK.in_namespace(ns): T.NAMESPACED_CLOCK.type})
    proc = _cli("replay", str(out), "--namespace", ns, "--rate", "40", "--wait", "30",
                "--json")
    try:
        pose_topic = T.TOOL_POSE.in_namespace(ns)
        last_pose = bag["/tool/pose"][-1]
        ros.spin_until(lambda: any(m.stamp_ns(x.header.stamp) == last_pose
                                   for x in rec[pose_topic][-3:]), TIMEOUT_S,
                       "the record's last /tool/pose replayed")
        out_text, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    result = json.loads(out_text.strip().splitlines()[-1])
    assert result["messages"]["/tool/pose"] == len(bag["/tool/pose"])
    # what arrived carries the bag's own stamps, in their order
    for topic, name in ((pose_topic, "/tool/pose"),
                        (T.MEASURED_PROFILE.in_namespace(ns), "/sheet/measured_profile")):
        got = [m.stamp_ns(x.header.stamp) for x in rec[topic]]
        assert got and set(got) <= set(bag[name]), topic
        assert got == sorted(got), topic
    clocks = [m.stamp_ns(x.clock) for x in rec[T.NAMESPACED_CLOCK.in_namespace(ns)]]
    assert clocks and set(clocks) <= {t for ts_ in bag.values() for t in ts_}


def test_record_cell_timeout_is_the_whole_wait_with_no_cell(tmp_path):
    """`record-cell --timeout 3` with no cell running waited 62 s (a fixed 60 s for the
    simulator's parameters): the timeout is one wall-clock budget for every phase."""
    t0 = time.monotonic()
    proc = subprocess.run([str(BIN / "rheo-shaping"), "record-cell", "--out",
                           str(tmp_path / "rec"), "--namespace", "/nobody_here",
                           "--timeout", "3"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True, timeout=120)
    took = time.monotonic() - t0
    assert proc.returncode == 2, proc.stderr
    assert "no /nobody_here/simulator/get_parameters service within 3 s" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert took < 30.0, f"{took:.1f} s for --timeout 3 (the ROS start-up included)"
