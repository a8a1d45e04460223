"""The ROS tools find the cell's clock and its frame in a namespace, without remaps.

A cell in a namespace (``rheo-shaping cell --namespace /tfcell``, the three nodes on the
default clock topic) is watched the way the standard tools watch it: an rclpy node in the
cell's namespace on ``use_sim_time`` (as rviz2 started there, no ``-r /clock:=clock``), and
a recorder of the absolute ``/clock`` and ``/tf_static`` (as ``ros2 bag record``) with tf2's
listener QoS, one of them joining after the frame went out.  The viewer's clock advances
with the cell's, the frame ``cake`` arrives under the configured parent and pose, and the
cell, whose planner and monitor follow the same absolute clock, runs its plan to the end.
"""
from __future__ import annotations

import json
import math
import os
import subprocess

import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

from rheo_shaping.nodes import topics as T  # noqa: E402
from rheo_shaping.units import NS  # noqa: E402

from _support.ros import BIN, Recorder  # noqa: E402

TFMessage = pytest.importorskip(
    "tf2_msgs.msg", reason="tf2_msgs is missing: python3 dev.py setup builds it").TFMessage

NAMESPACE = "/tfcell"
PARENT, XYZ, YAW = "table", [0.5, -0.25, 0.75], math.pi / 2
#: tf2_ros's TransformListener subscribes /tf_static so (its StaticListenerQoS, Jazzy).
TF_LISTENER_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
START_TIMEOUT_S = 120.0     # the process settles its sheet and plans on a busy machine
RUN_TIMEOUT_S = 240.0


def _params(tmp_path) -> str:
    path = tmp_path / "tf_cell.yaml"
    path.write_text(
        "/**:\n  ros__parameters:\n    sheet:\n      n_masses: 15\n"
        "/**/simulator:\n  ros__parameters:\n"
        f"    cake_parent_frame: {PARENT}\n    cake_xyz: {XYZ}\n"
        f"    cake_rpy: [0.0, 0.0, {YAW!r}]\n")
    return str(path)


def _cake(rec, topic: str):
    """The cake transform among the latched /tf_static messages received (None yet)."""
    for msg in reversed(rec[topic]):
        for t in msg.transforms:
            if t.child_frame_id == "cake":
                return t
    return None


def test_a_namespaced_cell_shows_its_clock_and_cake_frame_to_tools_without_remaps(
        ros, tmp_path):
    log = open(tmp_path / "cell.log", "w")
    proc = subprocess.Popen(
        [str(BIN / "rheo-shaping"), "cell", "--namespace", NAMESPACE, "--json", "--params",
         _params(tmp_path), "--real-time-factor", "20", "--timeout", str(RUN_TIMEOUT_S)],
        stdout=subprocess.PIPE, stderr=log, text=True, env=dict(os.environ),
        start_new_session=True)
    try:
        # rviz2 in the cell's namespace: use_sim_time, no remaps
        viewer = ros.node("rviz_like", namespace=NAMESPACE,
                          parameter_overrides=[Parameter("use_sim_time", value=True)])
        # ros2 bag record /clock /tf_static: absolute names, from the root
        bag = ros.node("bag_like")
        rec = Recorder(bag, {T.CLOCK.name: T.CLOCK.type})
        rec.add(T.TF_STATIC, TFMessage, TF_LISTENER_QOS)

        def alive():
            if proc.poll() is not None:
                pytest.fail(f"the cell exited early ({proc.returncode}): "
                            f"{(tmp_path / 'cell.log').read_text()[-3000:]}")

        ros.spin_until(lambda: viewer.get_clock().now().nanoseconds > 0, START_TIMEOUT_S,
                       f"the viewer in {NAMESPACE} to get the cell's clock", every=alive)
        t0 = viewer.get_clock().now().nanoseconds
        ros.spin_until(lambda: viewer.get_clock().now().nanoseconds >= t0 + NS, 60.0,
                       "the viewer's clock to advance by 1 s of the cell's time", every=alive)
        ros.spin_until(lambda: len({c.clock.sec for c in rec[T.CLOCK.name]}) >= 2, 60.0,
                       "the recorder's /clock to advance", every=alive)
        assert bag.count_publishers(T.NAMESPACED_CLOCK.in_namespace(NAMESPACE)) == 0

        # the frame, to a recorder that was there and to one that joins late (latched)
        late = Recorder(ros.node("tf_late"), {})
        late.add(T.TF_STATIC, TFMessage, TF_LISTENER_QOS)
        for r, who in ((rec, "the recorder"), (late, "a late tf2 listener")):
            ros.spin_until(lambda: _cake(r, T.TF_STATIC) is not None, 30.0,
                           f"the cake frame on /tf_static for {who}", every=alive)
            t = _cake(r, T.TF_STATIC)
            assert t.header.frame_id == PARENT
            tr, q = t.transform.translation, t.transform.rotation
            assert [tr.x, tr.y, tr.z] == XYZ
            s = math.sin(YAW / 2)
            assert [q.x, q.y, q.z, q.w] == pytest.approx([0.0, 0.0, s, math.cos(YAW / 2)],
                                                         abs=1e-12)

        # the cell itself followed the one absolute clock: its plan ran to its end (a
        # stale-data abort of a starved machine, docs/safety.md, is not this test's subject;
        # a clock fault would be)
        while proc.poll() is None:
            ros.spin_for(0.2)
        result = json.loads(proc.stdout.read().strip().splitlines()[-1])
        assert proc.returncode in (0, 3) and result["finished"], result
        assert "clock" not in result["abort_reason"], result["abort_reason"]
        if result["aborted"]:
            print(f"\nthe cell aborted (not a clock fault): {result['abort_reason']}")
        else:
            assert result["planner_state"] == "done", result
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        log.close()


def test_without_tf2_msgs_the_simulator_says_so_once_and_runs(ros, monkeypatch):
    """tf2_msgs is not everywhere (no wheel on PyPI): the simulator runs without /tf_static,
    and the process says why once."""
    import sys
    from rclpy.impl.rcutils_logger import RcutilsLogger
    from rheo_shaping.nodes import frames
    from rheo_shaping.nodes.simulator import SimulatorNode
    monkeypatch.setitem(sys.modules, "tf2_msgs.msg", None)      # its import fails
    monkeypatch.setattr(frames, "_said_missing", False)
    said = []
    warning = RcutilsLogger.warning

    def spy(self, message, **kwargs):
        if T.TF_STATIC in str(message):
            said.append(message)
        return warning(self, message, **kwargs)

    monkeypatch.setattr(RcutilsLogger, "warning", spy)
    small = [Parameter("sheet.n_masses", value=15)]
    sims = [ros.add(SimulatorNode(context=ros.context, namespace=f"/{name}",
                                  parameter_overrides=small)) for name in ("sim_a", "sim_b")]
    assert all(s.pub_tf_static is None for s in sims)
    assert all(e.topic_name != T.TF_STATIC for s in sims for e in s.publishers)
    assert len(said) == 1 and "tf2_msgs does not import" in said[0], said


def test_cake_rpy_turns_about_the_parents_fixed_axes():
    """cake_rpy as static_transform_publisher takes it: roll about x, then pitch about y,
    then yaw about z, all of the parent (scipy's extrinsic 'xyz')."""
    import numpy as np
    from scipy.spatial.transform import Rotation
    from rheo_shaping.nodes.frames import quaternion_from_rpy
    for rpy in ((0.3, -0.7, 1.9), (1.0, 0.2, -2.5), (0.0, 0.0, 0.0)):
        q = np.array(quaternion_from_rpy(*rpy))
        want = Rotation.from_euler("xyz", rpy).as_quat()          # (x, y, z, w)
        assert np.allclose(q, want, atol=1e-12) or np.allclose(q, -want, atol=1e-12), rpy
