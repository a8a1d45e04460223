"""Helpers of the ROS 2 tests (imported by conftest.py and the tests): contexts, bounded
spinning, recorders, matched-endpoint waits.

Every wait here is bounded and polls a condition (a matched endpoint, a
message, a state); nothing sleeps blindly.  test/conftest.py has already set
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a private ROS_DOMAIN_ID.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import pytest

rclpy = pytest.importorskip("rclpy", reason="rclpy is not installed: run in the full venv (.venv)")

from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def _bin() -> Path:
    """Where the node executables are: the venv's scripts (pip install -e), else the
    package's ``lib/rheo_shaping`` in an ament prefix (``colcon build`` then ``colcon
    test``: AMENT_PREFIX_PATH)."""
    here = Path(sys.executable).parent
    if (here / "simulator").exists():
        return here
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        lib = Path(prefix) / "lib" / "rheo_shaping"
        if prefix and (lib / "simulator").exists():
            return lib
    return here


BIN = _bin()          # the console scripts (simulator, planner, monitor, rheo-shaping)


class Ros:
    """One rclpy context with an executor the test spins in its own thread."""

    def __init__(self):
        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes = []

    def add(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def node(self, name: str, **kwargs):
        return self.add(rclpy.create_node(name, context=self.context, **kwargs))

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.01, max(end - time.monotonic(), 0.0)))

    def spin_until(self, predicate: Callable[[], bool], timeout: float, what: str = "",
                   every: Callable[[], None] | None = None) -> float:
        """Spin until ``predicate()`` holds; returns the wall time it took; fails after
        ``timeout``."""
        t0 = time.monotonic()
        while not predicate():
            if time.monotonic() - t0 > timeout:
                pytest.fail(f"timed out after {timeout:g} s waiting for {what or predicate}")
            if every is not None:
                every()
            self.executor.spin_once(timeout_sec=0.01)
        return time.monotonic() - t0

    def close(self):
        self.executor.shutdown(timeout_sec=1.0)
        for node in reversed(self.nodes):
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture
def ros():
    r = Ros()
    try:
        yield r
    finally:
        r.close()


class Recorder:
    """Subscribes to topics and keeps every message with its arrival index and its
    rmw message info (``infos[topic][i]``: ``source_timestamp`` [ns, the publisher's system
    clock], ``publication_sequence_number``, ...), which tells one sender from another."""

    def __init__(self, node, topics: dict, qos=None):
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        self.node = node
        self.msgs: dict[str, list] = {t: [] for t in topics}
        self.infos: dict[str, list] = {t: [] for t in topics}
        self.order: list[tuple[str, int]] = []
        self.subs = []
        for topic, spec in topics.items():
            msg_type, latched = spec if isinstance(spec, tuple) else (spec, False)
            q = qos or QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                                  durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                              else DurabilityPolicy.VOLATILE))
            self.subs.append(node.create_subscription(msg_type, topic, self._cb(topic), q))

    def add(self, topic: str, msg_type, qos) -> None:
        """Record one more topic, with a QoS of its own."""
        self.msgs[topic], self.infos[topic] = [], []
        self.subs.append(self.node.create_subscription(msg_type, topic, self._cb(topic), qos))

    def _cb(self, topic):
        def cb(msg, info):
            self.order.append((topic, len(self.msgs[topic])))
            self.msgs[topic].append(msg)
            self.infos[topic].append(info)
        return cb

    def published_after(self, topic, wall_ns: int) -> list:
        """Messages on ``topic`` whose publisher sent them after ``wall_ns`` (time.time_ns()):
        a message still in flight from before then is not among them."""
        return [msg for msg, info in zip(self.msgs[topic], self.infos[topic])
                if info["source_timestamp"] > wall_ns]

    def lost(self, topic) -> int:
        """Messages on ``topic`` its publisher sent that this recorder never got: the gaps in
        the publication sequence numbers (one publisher on the topic), counted from the first
        message received to the last."""
        seq = [info["publication_sequence_number"] for info in self.infos[topic]]
        return sum(b - a - 1 for a, b in zip(seq, seq[1:]) if b > a + 1)

    def __getitem__(self, topic):
        return self.msgs[topic]

    def last(self, topic):
        return self.msgs[topic][-1] if self.msgs[topic] else None


def wait_for_publishers(ros: Ros, node, topics, timeout: float = 20.0, count: int = 1) -> None:
    """Matched-endpoint wait: every topic has at least ``count`` publishers in the graph."""
    ros.spin_until(lambda: all(node.count_publishers(t) >= count for t in topics), timeout,
                   f"publishers on {topics}")


def wait_for_subscribers(ros: Ros, publisher, timeout: float = 20.0, count: int = 1) -> None:
    ros.spin_until(lambda: publisher.get_subscription_count() >= count, timeout,
                   f"{count} subscriber(s) of {publisher.topic_name}")


# -- processes -------------------------------------------------------------------------
class Proc:
    """A node executable started as its own process; output to a log file."""

    def __init__(self, exe: str, args: list[str], log: Path):
        self.exe, self.log = exe, log
        self.out = open(log, "w")
        self.proc = subprocess.Popen(
            [str(BIN / exe), *args], stdin=subprocess.DEVNULL, stdout=self.out,
            stderr=subprocess.STDOUT, env=dict(os.environ), start_new_session=True)

    def text(self) -> str:
        if not self.out.closed:
            self.out.flush()
        return self.log.read_text(errors="replace")

    def stop(self, timeout: float = 15.0) -> int:
        """SIGINT, then wait; kill (and fail later) if it does not exit."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
                self.out.close()
                return -9
        self.out.close()
        return self.proc.returncode


@pytest.fixture
def procs(tmp_path):
    """Start node executables; all are stopped (SIGINT) at the end, killed if they hang."""
    started: list[Proc] = []

    def start(exe: str, *args: str) -> Proc:
        p = Proc(exe, list(args), tmp_path / f"{exe}-{len(started)}.log")
        started.append(p)
        return p

    start.all = started
    try:
        yield start
    finally:
        for p in started:
            if p.proc.poll() is None:
                p.stop(timeout=5.0)


# -- motion checks --------------------------------------------------------------------
def executed(cmds, infos=None):
    """(stamps [ns], positions [m]) of the path a simulator follows from set-point messages:
    a set-point for a time already commanded replaces what followed (the planner's stop,
    re-planned from the executed pose, supersedes what it had sent ahead).  With ``infos``
    (the recorder's message infos of the same messages) a third array follows: each kept
    set-point's publication sequence number, which tells a set-point the observer missed
    (two kept neighbours more than 1 apart) from one that was never sent."""
    import numpy as np
    from rheo_shaping.nodes import messages as m
    seqs = ([i["publication_sequence_number"] for i in infos] if infos is not None
            else [0] * len(cmds))
    path: list = []
    for c, seq in zip(cmds, seqs):
        t = m.stamp_ns(c.header.stamp)
        while path and path[-1][0] >= t:
            path.pop()
        path.append((t, m.pose_xz(c), seq))
    out = (np.array([q[0] for q in path], dtype=np.int64),
           np.array([q[1] for q in path], dtype=float).reshape(-1, 2))
    if infos is None:
        return out
    return out + (np.array([q[2] for q in path], dtype=np.int64),)


def motion_bounds(t_ns, p, min_gap: float = 1e-4):
    """Largest speed, acceleration and jerk a C2 motion through the points can have locally:
    1!, 2! and 3! times the divided differences (exact averages of the derivative weighted by
    a positive B-spline kernel, so each is bounded by the derivative's largest value).
    Points closer than ``min_gap`` [s] to the previous one are dropped (round-off)."""
    import numpy as np
    t = np.asarray(t_ns, dtype=float) / 1e9
    p = np.asarray(p, dtype=float)
    keep = np.concatenate([[True], np.diff(t) > min_gap])
    t, p = t[keep], p[keep]
    d1 = np.diff(p, axis=0) / np.diff(t)[:, None]
    d2 = np.diff(d1, axis=0) / (t[2:] - t[:-2])[:, None]
    d3 = np.diff(d2, axis=0) / (t[3:] - t[:-3])[:, None]
    return tuple(float(k * np.linalg.norm(d, axis=1).max(initial=0.0))
                 for k, d in ((1, d1), (2, d2), (6, d3)))
