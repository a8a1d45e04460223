"""ROS 2 rigs shared by the node tests: the cell as three processes, and a fake cell
that feeds an in-process monitor (they need rclpy)."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseArray, PoseStamped, WrenchStamped  # noqa: E402
from rclpy.duration import Duration  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Bool, Float64, Float64MultiArray, String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402

from rheo_shaping.nodes import messages as m  # noqa: E402
from rheo_shaping.nodes.topics import LATCHED_QOS  # noqa: E402
from rheo_shaping.params.fingerprint import cell_message  # noqa: E402
from rheo_shaping.nodes.monitor import MonitorNode  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.units import NS  # noqa: E402

from .ros import Recorder, executed, wait_for_publishers, wait_for_subscribers  # noqa: E402

F_BREAK = CellParams().material.F_break
N_LINKS = CellParams().sheet.n_masses + 1


#: The streams the rig records: every message of each (reliable, 1000 deep).
STREAMS = {"/sheet/profile": PoseArray, "/sheet/tensions": Float64MultiArray,
           "/tool/command": PoseStamped, "/tool/pose": PoseStamped}
#: The latched topics it records (transient local: a late observer still gets the last one).
LATCHED = {"/tool/planned_trajectory": JointTrajectory, "/shaping/planner_state": String,
           "/shaping/abort": String}
#: A sampled stream keeps only the newest message whenever the observer reads: it costs the
#: observer's Python one read per executor cycle instead of one per message (DDS's reader
#: thread overwrites the rest), so a fast stream cannot crowd out the others.
SAMPLED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)


class Cell:
    """The three processes and a recording test node.

    ``streams``: the topics of :data:`STREAMS` recorded in full (default: all of them);
    ``sampled``: topics recorded as a sample (:data:`SAMPLED_QOS`).  The observer is one Python
    process: measured here (benchmarks/observer_capacity.py), it took 1,200 messages/s without
    loss on an idle machine but lost some at 2,000/s, and with a CPU hog on both cores 600/s
    without loss but lost a third at 1,200/s.  So a test records only what it checks, at a
    real-time factor that keeps its full streams well below that."""

    def __init__(self, ros, procs, params, sim_time: bool = True,
                 streams: tuple[str, ...] | None = None, sampled: tuple[str, ...] = ()):
        self.ros, self.procs = ros, procs
        files = [a for p in (params if isinstance(params, list) else [params])
                 for a in ("--params-file", str(p))]
        follow = ["-p", "use_sim_time:=true"] if sim_time else []
        self.sim = procs("simulator", "--ros-args", *files)
        self.planner = procs("planner", "--ros-args", *files, *follow)
        self.monitor = procs("monitor", "--ros-args", *files, *follow)
        self.node = ros.node("e2e_observer")
        full = [t for t in (STREAMS if streams is None else streams) if t not in sampled]
        self.rec = Recorder(self.node, {**{t: STREAMS[t] for t in full},
                                        **{t: (ty, True) for t, ty in LATCHED.items()}})
        for topic in sampled:
            self.rec.add(topic, STREAMS[topic], SAMPLED_QOS)

    def logs(self) -> str:
        return "\n".join(f"--- {p.exe} ---\n{p.text()[-4000:]}" for p in self.procs.all)

    def wait(self, predicate, timeout, what):
        t0 = time.monotonic()
        while not predicate():
            for p in self.procs.all:
                if p.proc.poll() is not None:
                    pytest.fail(f"{p.exe} exited with {p.proc.returncode} while waiting for "
                                f"{what}\n"
                                + self.logs())
            if time.monotonic() - t0 > timeout:
                pytest.fail(f"timed out after {timeout:g} s waiting for {what}\n" + self.logs())
            self.ros.executor.spin_once(timeout_sec=0.01)
        return time.monotonic() - t0

    def start(self):
        """Matched endpoints and the interlock first, then ~/start."""
        wait_for_publishers(self.ros, self.node,
                            ["/sheet/profile", "/sheet/tensions", "/tool/pose",
                             "/shaping/planner_state"], timeout=60.0)
        self.wait(lambda: (len(self.rec["/sheet/tensions"]) >= 3
                           and len(self.rec["/sheet/profile"]) >= 3),
                  60.0, "sheet data reaching the test")
        self.wait(lambda: self.state() == "idle", 60.0, "the planner (autostart off) to be idle")
        client = self.node.create_client(Trigger, "/planner/start")
        self.wait(client.service_is_ready, 30.0, "/planner/start")
        future = client.call_async(Trigger.Request())
        self.wait(future.done, 10.0, "/planner/start response")
        assert future.result().success, future.result().message

    def state(self) -> str:
        s = self.rec.last("/shaping/planner_state")
        return s.data if s else ""

    def stop_all(self):
        codes = {p.exe: p.stop() for p in self.procs.all}
        assert all(c == 0 for c in codes.values()), f"exit codes {codes}\n" + self.logs()

    # -- what the topics say ---------------------------------------------------------
    def t0(self) -> int:
        return m.stamp_ns(self.rec["/tool/planned_trajectory"][0].header.stamp)

    def tension_samples(self):
        """(stamp of the profile published with it, largest tension) per /sheet/tensions message.

        /sheet/tensions has no header: the simulator publishes /sheet/profile and then
        /sheet/tensions in the same step, so each tension message is paired with the
        profile that arrived before it."""
        out, stamp = [], None
        for topic, i in self.rec.order:
            if topic == "/sheet/profile":
                stamp = m.stamp_ns(self.rec[topic][i].header.stamp)
            elif topic == "/sheet/tensions" and stamp is not None:
                out.append((stamp, float(np.max(self.rec[topic][i].data))))
        return np.array(out, dtype=float).reshape(-1, 2)

    def commands(self, with_seq: bool = False):
        """The executed set-point path (:func:`_support.ros.executed`); ``with_seq``: with
        each set-point's publication sequence number as a third array."""
        if with_seq:
            return executed(self.rec["/tool/command"], self.rec.infos["/tool/command"])
        return executed(self.rec["/tool/command"])


class FakeCell:
    """Publishes /clock (simulated time it controls) and the tension/stamped topics."""

    def __init__(self, ros):
        self.ros = ros
        # named as the simulator: the monitor takes the tensions from no other node
        self.node = ros.node("simulator")
        q = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                       deadline=Duration(seconds=0.05))
        self.clock = self.node.create_publisher(Clock, "/clock", 1)
        self.tensions = self.node.create_publisher(Float64MultiArray, "/sheet/tensions", q)
        self.contact = self.node.create_publisher(Float64, "/sheet/contact_tension", q)
        self.profile = self.node.create_publisher(PoseArray, "/sheet/profile", 10)
        self.wrench = self.node.create_publisher(WrenchStamped, "/tool/wrench", 10)
        # the simulator's cell (latched): the monitor is ready only on its own cell
        self.cell = self.node.create_publisher(String, "/shaping/cell", LATCHED_QOS)
        self.cell.publish(String(data=cell_message(CellParams())))
        self.t_ns = 10 * NS
        self.sent = 0          # samples published (= the tension writer's sequence number)

    def publish(self, tension=0.2, contact=0.1, stamp_ns=None, dt=0.05):
        """One sample of the cell at simulated time t (advanced by dt)."""
        self.t_ns += int(dt * NS)
        self.clock.publish(m.clock_msg(self.t_ns))
        stamp = self.t_ns if stamp_ns is None else stamp_ns
        self.profile.publish(m.profile_msg([[0.01, 0.05]], stamp))
        self.wrench.publish(m.wrench_msg([0.0, 0.0], stamp))
        # the default cell's sheet: n_masses + 1 link tensions (the monitor checks the count)
        values = tension if isinstance(tension, list) else [0.1, tension] + [0.05] * (N_LINKS - 2)
        self.tensions.publish(m.tensions_msg(values))
        self.sent += 1
        self.contact.publish(m.float_msg(contact))

    def stream(self, seconds, **kw):
        """Publish samples every 20 ms of wall time for ``seconds``, spinning meanwhile."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.publish(**kw)
            self.ros.spin_for(0.02)


def make_monitor(ros, **settings):
    # fixed: no core runs for the budget (tested below)
    settings.setdefault("abort_ratio", 0.6)
    # the fake cells here do not wait for the acknowledgements: not a lockstep cell, so
    # staleness on the wall's clock (stale_clock 'auto' is the cell's in a lockstep cell)
    settings.setdefault("stale_clock", "wall")
    overrides = [Parameter("use_sim_time", value=True)]
    overrides += [Parameter(k, value=v) for k, v in settings.items()]
    return ros.add(MonitorNode(context=ros.context, parameter_overrides=overrides))


def listen(ros):
    node = ros.node("monitor_listener")
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    rec = Recorder(node, {"/shaping/ready": Bool, "/diagnostics": DiagnosticArray})
    rec.add("/shaping/abort", String, latched)
    return node, rec


def get_ready(ros, monitor, cell):
    wait_for_subscribers(ros, cell.tensions)
    wait_for_subscribers(ros, cell.profile)
    ros.spin_until(lambda: monitor.ready, 10.0, "monitor ready",
                   every=lambda: cell.publish())


@dataclass
class WatchdogTick:
    """One check of an in-process monitor's watchdog, as the node made it."""

    steady: int                       # the monitor's steady clock at the check [ns]
    stalled: bool                     # the node stood still before it (StallGuard)
    ages: dict[str, float]            # each tension stream's age at the check [s]
    age_at_previous: float            # the oldest one's age at the previous check [s] (inf: none)
    state_before: str
    state_after: str

    @property
    def age(self) -> float:
        """The oldest tension stream's age at the check [s]."""
        return max(self.ages.values())


@dataclass
class WatchdogLog:
    """The watchdog checks of an in-process monitor, and when it aborted."""

    ticks: list[WatchdogTick]
    abort_at: int | None = None       # the checks done before the abort (its tick's index)


def record_watchdog(monitor: MonitorNode) -> WatchdogLog:
    """Every later watchdog check of ``monitor`` (its core's ``tick``, wrapped) in order, and
    the number of checks done when it aborted (an abort inside check i counts i)."""
    core = monitor.core
    tick, abort = core.tick, core.abort
    log = WatchdogLog([])

    def recorded_tick(steady: int, clock: int, stalled: bool = False,
                      previous: int | None = None) -> bool:
        ages = {t: core.age(t, steady) for t in core.tension_topics}
        before = (max(core.age(t, previous) for t in core.tension_topics)
                  if previous is not None else float("inf"))
        state = core.state
        ready = tick(steady, clock, stalled, previous)
        log.ticks.append(WatchdogTick(steady, stalled, ages, before, state, core.state))
        return ready

    def recorded_abort(reason: str) -> bool:
        if core.state != "aborted":
            log.abort_at = len(log.ticks)
        return abort(reason)

    core.tick, core.abort = recorded_tick, recorded_abort
    return log
