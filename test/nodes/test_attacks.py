"""Rogue, frozen and lying inputs against the three node processes (issue 27, docs/safety.md).

The cell runs a "tear plan": movement 3 at 2 mm/s, which reaches 1.25 N without the monitor
(F_break 1.04 N; the monitor alone stops it at about 0.98 N).  Each test attacks the running
cell as an outsider could on the same ROS domain (a second commander, a forged /clock, a
frozen monitor, a twin node, lying tension data, a parameter slip, a spoofed heartbeat, the
planner killed with SIGKILL and restarted) and
checks what matters: the largest tension the simulator computed (its own F_max on
/diagnostics, every step counted, not only what reached the test) stays below the abort
threshold plus what the stopping budget allows and below F_break, the reason is named, and
no process prints a traceback.
"""
from __future__ import annotations

import math
import os
import random
import signal
import time
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseStamped  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Bool, Float64MultiArray, String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from rheo_shaping.nodes import messages as m  # noqa: E402
from rheo_shaping.safety.abort_budget import abort_horizon, configured_speed_threshold  # noqa: E402,E501
from rheo_shaping.units import NS  # noqa: E402

from _support.cells import base_cell, write_params  # noqa: E402
from _support.rigs import Cell  # noqa: E402
from _support.ros import Recorder  # noqa: E402

#: process time [s] at which an attack starts: the tear plan's tension is still low then
#: (about 0.5 N; the threshold is crossed near 16 s).  benchmarks/attack_campaign.py draws
#: it per run (RHEO_ATTACK_SEED: uniform in [2, 14] s) and sets the simulator's real-time
#: factor (RHEO_ATTACK_RTF, default 10).
_SEED = os.environ.get("RHEO_ATTACK_SEED")
ATTACK_AT = random.Random(int(_SEED)).uniform(2.0, 14.0) if _SEED else 5.0
RTF = float(os.environ.get("RHEO_ATTACK_RTF", "10"))
#: wall time per simulator step [s]: a step of simulated time no shorter than the planner's
#: control period (20 ms), so lockstep finds each step's set-point streamed
STEP = 0.01 if RTF >= 2 else 0.02


def tear_cell():
    base = base_cell()
    return replace(base, movement=replace(base.movement, number=3, speed=0.002))


class Attacked:
    """The tear plan's cell as three processes, with what the attacks need."""

    def __init__(self, ros, procs, tmp_path, rtf=RTF, simulator=None, planner=None,
                 monitor=None):
        self.cell = tear_cell()
        self.params = write_params(
            tmp_path / "tear.yaml", self.cell,
            simulator={"real_time_factor": rtf, "step_period": STEP, "diagnostics_period": 0.2,
                       "publish_clock": True,            # at x1 too: the cell's clock
                       **(simulator or {})},
            planner={"autostart": False, **(planner or {})},
            monitor={"max_data_age": 0.5, **(monitor or {})})
        self.c = Cell(ros, procs, self.params, streams=(),
                      sampled=("/sheet/profile", "/sheet/tensions", "/tool/pose"))
        self.ros, self.procs = ros, procs
        self.diag = Recorder(self.c.node, {"/diagnostics": DiagnosticArray})
        h = abort_horizon(self.cell, 0.1, 0.0)
        self.threshold, self.rate, _ = configured_speed_threshold(self.cell, h, 0.005)
        self.horizon = h

    # -- what the cell says -----------------------------------------------------------
    def sim_values(self) -> dict:
        """The newest /diagnostics values of the simulator."""
        for msg in reversed(self.diag["/diagnostics"]):
            for st in msg.status:
                if st.name == "rheo_shaping/simulator":
                    return {kv.key: kv.value for kv in st.values} | {"_message": st.message}
        return {}

    def process_time(self) -> float:
        pose = self.c.rec.last("/tool/pose")
        return ((m.stamp_ns(pose.header.stamp) - self.c.t0()) / NS
                if pose is not None and self.c.rec["/tool/planned_trajectory"] else -1.0)

    def aborts(self) -> list[str]:
        return [a.data for a in self.c.rec["/shaping/abort"]]

    def run_to(self, t_process: float) -> None:
        self.c.start()
        self.c.wait(lambda: self.process_time() >= t_process, 60.0,
                    f"process time {t_process:g} s")

    def peak_after_hold(self) -> float:
        """The simulator's F_max once the tool holds and 2 s of wall time went by."""
        self.c.wait(lambda: "holds" in self.sim_values().get("_message", ""), 20.0,
                    "the simulator's tool to hold")
        n = len(self.diag["/diagnostics"])
        t_end = time.monotonic() + 2.0
        self.c.wait(lambda: time.monotonic() > t_end and len(self.diag["/diagnostics"]) > n,
                    20.0, "2 s more of the simulator's diagnostics")
        return float(self.sim_values()["F_max"])

    def check(self, F_max: float) -> None:
        """Below the threshold + the budget's allowance, below F_break; no traceback."""
        Fb = self.cell.material.F_break
        allowed = self.threshold + self.rate * self.horizon
        print(f"\nF_max {F_max:.4f} N (threshold {self.threshold:.4f} N, allowed "
              f"{allowed:.4f} N, F_break {Fb:g} N); aborts: {self.aborts()}")
        tracebacks = [p.exe for p in self.procs.all if "Traceback" in p.text()]
        print(f"process tracebacks: {len(tracebacks)} {tracebacks}")
        assert F_max < allowed and F_max < Fb
        assert not tracebacks, self.c.logs()

    def stop(self, allowed_codes=None) -> None:
        codes = {p.exe + str(i): p.stop() for i, p in enumerate(self.procs.all)}
        bad = {k: v for k, v in codes.items() if v != 0 and v not in (allowed_codes or ())}
        assert not bad, f"exit codes {codes}\n" + self.c.logs()


def _rogue_tensions(a, ros):
    """A publisher of /sheet/tensions the monitor takes: it offers the QoS deadline the
    monitor requests (a writer without one does not match its reader at all)."""
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    q = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                   deadline=Duration(seconds=0.05))
    bad = ros.node("rogue_tensions").create_publisher(Float64MultiArray, "/sheet/tensions", q)
    # the test's own observer and the monitor
    a.c.wait(lambda: bad.get_subscription_count() >= 2, 20.0, "the monitor to match")
    return bad


def _lie_until_abort(a, ros, values=(0.1,)):
    """Publish a lying /sheet/tensions sample until the monitor has aborted on it."""
    bad = _rogue_tensions(a, ros)
    k = len(a.aborts())
    t_end = time.monotonic() + 20.0
    while len(a.aborts()) == k and time.monotonic() < t_end:
        bad.publish(m.tensions_msg(list(values)))
        ros.spin_for(0.05)
    # an abort the cell had latched already (a busy machine's stale data) stops it as well
    assert len(a.aborts()) > k or a.aborts(), "no abort on lying data"


def _off_plan(a, xz, since: float) -> float:
    """Distance [m] of the point ``xz`` from the planned path (/tool/planned_trajectory, a
    polyline through its points) from process time ``since`` - 0.5 s on."""
    traj = a.c.rec["/tool/planned_trajectory"][0]             # the plan (t0 of process time)
    t = np.array([p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in traj.points])
    pts = np.array([p.positions[:2] for p in traj.points])[t >= since - 0.5]
    if len(pts) < 2:
        return float(np.hypot(*(pts[0] - xz))) if len(pts) else math.inf
    p, q = pts[:-1], pts[1:]
    d = q - p
    u = np.clip(np.einsum("ij,ij->i", np.asarray(xz) - p, d)
                / np.maximum(np.einsum("ij,ij->i", d, d), 1e-30), 0.0, 1.0)
    return float(np.min(np.hypot(*(p + u[:, None] * d - np.asarray(xz)).T)))


def _publish_for(ros, pub, make, seconds, period=0.02):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        pub.publish(make())
        ros.spin_for(period)


@pytest.mark.parametrize("after_abort", [False, True], ids=["during_run", "after_abort"])
def test_a_second_commander_is_refused_and_the_tool_holds(ros, procs, tmp_path, after_abort):
    a = Attacked(ros, procs, tmp_path)
    a.run_to(ATTACK_AT)
    if after_abort:                 # the cell already stopped: the rogue must not move it
        _lie_until_abort(a, ros)                 # lying data: the monitor aborts
    rogue = ros.node("rogue_commander").create_publisher(PoseStamped, "/tool/command", 10)
    pose = a.c.rec.last("/tool/pose")
    x, z = m.pose_xz(pose)
    t_rogue = a.process_time()
    # a plausible-looking set-point 35 mm back along x, stamped like the planner's
    _publish_for(ros, rogue, lambda: m.pose_msg((x - 0.035, z), m.stamp_ns(
        a.c.rec.last("/tool/pose").header.stamp) + NS // 10), 2.0)
    F_max = a.peak_after_hold()
    held_at = m.pose_xz(a.c.rec.last("/tool/pose"))
    reasons = " | ".join(a.aborts())
    log = a.c.logs()
    if after_abort:                 # held before the rogue came: it stays where it was
        assert abs(held_at[0] - x) < 2e-3, (held_at, x)
        assert "ignoring /tool/command while the tool holds" in log
    else:
        # the planner's plan ran on until the simulator saw the rogue (at x10 that is
        # seconds of plan on a busy machine): the tool holds at a point of its own plan
        # reached after the rogue began, never on the way to the rogue's set-point
        off = _off_plan(a, held_at, t_rogue)
        assert off < 1e-4, f"held {off * 1e3:.3f} mm off the planned path: {held_at}"
        # the reason is the rogue's, unless the cell held already (a busy machine's stale
        # data came first: seen at x1 under load 15) and the simulator ignored the rogue
        assert ("a second publisher of /tool/command" in reasons
                or "out of the bound planner's sequence" in reasons
                or "ignoring /tool/command while the tool holds" in log), reasons
    a.check(F_max)
    a.stop()


@pytest.mark.parametrize("forged", ["+30s", "negative"])
def test_a_forged_clock_stops_the_run_with_the_reason(ros, procs, tmp_path, forged):
    a = Attacked(ros, procs, tmp_path, planner={"max_lead": 0.5})
    a.run_to(ATTACK_AT)
    rogue = ros.node("rogue_clock").create_publisher(Clock, "/clock", 1)
    a.c.wait(lambda: rogue.get_subscription_count() >= 2, 20.0, "planner and monitor to match")
    now = m.stamp_ns(a.c.rec.last("/tool/pose").header.stamp)
    msg = m.clock_msg(now + 30 * NS) if forged == "+30s" else Clock()
    if forged == "negative":
        msg.clock.sec = -5
    rogue.publish(msg)
    a.c.wait(lambda: a.aborts(), 20.0, "the abort")
    F_max = a.peak_after_hold()
    reasons = " | ".join(a.aborts()) + a.c.logs()
    want = "jumped forward by" if forged == "+30s" else "/clock is negative"
    # on a busy machine the tear plan may meet the monitor's threshold before the forged
    # message is read (seen at x10, load 15: the threshold abort at 16.1 s); that stop holds
    first = a.aborts()[0] if a.aborts() else ""
    assert (want in reasons or "publishers of /clock" in reasons
            or "reached the abort threshold" in first), reasons[-3000:]
    for p in procs.all:
        assert p.proc.poll() is None, f"{p.exe} died\n" + p.text()[-3000:]
    a.check(F_max)
    a.stop()


def test_a_frozen_monitor_holds_the_tool_within_the_budget(ros, procs, tmp_path):
    a = Attacked(ros, procs, tmp_path)
    a.run_to(ATTACK_AT)
    t_sim = float(a.sim_values().get("process_time", "nan"))
    a.c.monitor.proc.send_signal(signal.SIGSTOP)
    t_freeze = time.monotonic()
    try:
        a.c.wait(lambda: "monitor lost" in a.sim_values().get("_message", ""), 20.0,
                 "the simulator to see the frozen monitor")
        seen = time.monotonic() - t_freeze
        F_max = a.peak_after_hold()
        moved = float(a.sim_values()["process_time"]) - t_sim
        print(f"\nfrozen monitor seen by the simulator {seen:.3f} s (wall) after SIGSTOP")
    finally:
        a.c.monitor.proc.send_signal(signal.SIGCONT)
    a.c.wait(lambda: a.c.state() in ("stopping", "retracting", "holding"), 20.0,
             "the planner to stop")
    assert moved < 60.0
    a.check(F_max)
    a.stop()


def test_a_second_planner_yields_and_a_start_is_served_once(ros, procs, tmp_path):
    a = Attacked(ros, procs, tmp_path)
    a.run_to(ATTACK_AT)
    twin = procs("planner", "--ros-args", "--params-file", str(a.params),
                 "-p", "use_sim_time:=true")
    client = a.c.node.create_client(Trigger, "/planner/start")
    answers = []
    t_end = time.monotonic() + 20.0
    while twin.proc.poll() is None and time.monotonic() < t_end:
        if client.service_is_ready():
            fut = client.call_async(Trigger.Request())
            # the twin may yield (exit 2) with the call in flight: its answer never comes
            ros.spin_until(lambda: fut.done() or twin.proc.poll() is not None, 10.0,
                           "the start response")
            if fut.done():
                answers.append(fut.result())
        ros.spin_for(0.2)
    assert twin.proc.poll() == 2, twin.text()[-2000:]
    assert "yields" in twin.text() and "started first and runs" in twin.text()
    assert "starting the plan" not in twin.text()
    # the running planner refused every start ("already started"); a start the newcomer
    # took before the older one's announcement reached it was never served: it yielded
    # without a plan of its own (the one pass is the first planner's)
    took = [r.message for r in answers if r.success]
    print(f"\nstart answers: {len(answers)}, taken by the newcomer before it yielded: {took}")
    # (a refusal of the newcomer itself, on the cell's latched abort, is a refusal too)
    assert answers and all(r.success or "already started" in r.message
                           or r.message.startswith("aborted (") for r in answers), \
        [r.message for r in answers]
    procs.all.remove(twin)
    # the first planner ran on: its plan goes on, or the tear plan met the monitor's
    # threshold meanwhile (the twin takes seconds of wall time to start: tens of seconds of
    # process time at x10), or a busy machine's data went stale (seen at x1, load 15);
    # nothing stopped it on the twin's account (a second commander, heartbeat or clock)
    reasons = a.aborts()
    assert a.c.state() == "running" or all(
        "abort threshold" in r or r.startswith("stale data") for r in reasons), reasons
    assert len(a.c.rec["/tool/planned_trajectory"]) == 1        # one pass, the first one
    if reasons:
        a.check(a.peak_after_hold())
    a.stop()


def test_lying_tension_data_aborts_with_the_reason(ros, procs, tmp_path):
    a = Attacked(ros, procs, tmp_path)
    a.run_to(ATTACK_AT)
    rogue = _rogue_tensions(a, ros)
    n = a.cell.sheet.n_masses + 1
    reset = a.c.node.create_client(Trigger, "/monitor/reset")
    ready = Recorder(a.c.node, {"/shaping/ready": Bool})
    for i, (values, why) in enumerate((
            ([0.1], "has 1 links"), ([0.1] * 100_000, "has 100000 links"),
            ([0.1] * (n - 1) + [-5.0], "implausible tension -5 N"),
            ([0.1] * (n - 1) + [-1e300], "implausible tension -1e+300 N"))):
        k = len(a.aborts())
        t_end = time.monotonic() + 20.0
        while len(a.aborts()) == k and time.monotonic() < t_end:
            rogue.publish(m.tensions_msg(values))     # until the monitor's reader has it
            ros.spin_for(0.05)
        new = a.aborts()[k:]
        # on a busy machine the tear plan may meet the monitor's threshold before the
        # monitor's reader has the rogue's first message (attack campaign seed 36, x10: the
        # threshold abort at 0.9359 N, threshold 0.9274 N): that stop must hold (checked
        # below), and the lies are not judged in this run
        if i == 0 and new and "reached the abort threshold" in new[0]:
            break
        assert any(why in r for r in new), a.aborts()
        fut = reset.call_async(Trigger.Request())
        a.c.wait(fut.done, 10.0, "the monitor's reset")
        ready.msgs["/shaping/ready"].clear()
        a.c.wait(lambda: any(r.data for r in ready["/shaping/ready"]), 20.0,
                 "the monitor ready again")
    a.check(a.peak_after_hold())
    a.stop()


def test_a_parameter_slip_in_one_node_is_refused_with_both_values(ros, procs, tmp_path):
    cell = tear_cell()
    params = write_params(tmp_path / "tear.yaml", cell,
                          simulator={"real_time_factor": RTF, "step_period": STEP,
                                     "publish_clock": True},
                          planner={"autostart": False})
    sim = procs("simulator", "--ros-args", "--params-file", str(params))
    mon = procs("monitor", "--ros-args", "--params-file", str(params), "-p", "use_sim_time:=true")
    slip = procs("planner", "--ros-args", "--params-file", str(params), "-p",
                 "use_sim_time:=true", "-p", "movement.speed:=0.005", "-p", "movement.number:=2")
    node = ros.node("slip_observer")
    client = node.create_client(Trigger, "/planner/start")
    rec = Recorder(node, {"/tool/command": PoseStamped})
    ros.spin_until(client.service_is_ready, 60.0, "/planner/start")
    t_end = time.monotonic() + 60.0
    while "the cell differs" not in slip.text() and time.monotonic() < t_end:
        fut = client.call_async(Trigger.Request())
        # a response can be lost when the server has not yet matched this client's response
        # reader (rmw_fastrtps waits 100 ms for it: ros2/rmw_fastrtps#390, #467); the loop
        # then asks again, and the check is the planner's own log below
        t_call = time.monotonic()
        while not fut.done() and time.monotonic() - t_call < 10.0:
            ros.spin_for(0.1)
        ros.spin_for(0.5)
    text = slip.text()
    assert "the cell differs from the simulator's" in text, text[-3000:]
    assert "movement.number = 2 (the planner) vs 3 (the simulator)" in text
    assert "movement.speed = 0.005 (the planner) vs 0.002 (the simulator)" in text
    ros.spin_for(1.0)
    assert rec["/tool/command"] == []
    for p in (sim, mon, slip):
        assert "Traceback" not in p.text()
        assert p.stop() == 0


def test_a_spoofed_ready_heartbeat_does_not_open_the_interlock(ros, procs, tmp_path):
    """The monitor aborted (lying data) and the planner is re-armed: a second publisher of
    /shaping/ready saying true does not make it move."""
    a = Attacked(ros, procs, tmp_path)
    a.run_to(ATTACK_AT)
    _lie_until_abort(a, ros)
    a.c.wait(lambda: a.c.state() == "holding", 60.0, "the planner holding after the abort")
    spoof = ros.node("rogue_ready").create_publisher(Bool, "/shaping/ready", 1)
    reset = a.c.node.create_client(Trigger, "/planner/reset")
    a.c.wait(reset.service_is_ready, 10.0, "/planner/reset")
    fut = reset.call_async(Trigger.Request())
    a.c.wait(fut.done, 10.0, "the planner's reset")
    assert fut.result().success, fut.result().message
    start = a.c.node.create_client(Trigger, "/planner/start")
    fut = start.call_async(Trigger.Request())
    a.c.wait(fut.done, 10.0, "the start response")
    _publish_for(ros, spoof, lambda: Bool(data=True), 3.0, period=0.05)
    log = "".join(p.text() for p in procs.all if p.exe == "planner")
    assert a.c.state() in ("waiting_for_monitor", "idle", "holding"), a.c.state()
    assert "publishers of /shaping/ready" in log or a.c.state() == "waiting_for_monitor"
    a.check(a.peak_after_hold())
    a.stop()


def test_a_planner_killed_and_restarted_does_not_move_the_tool(ros, procs, tmp_path):
    """kill -9 of the planner mid-run, then a new planner with autostart on: the simulator
    holds the tool at its last set-point, and the new planner refuses to move a tool that
    is neither at home nor at the plan's start (or holds on an abort the cell latched)."""
    a = Attacked(ros, procs, tmp_path)
    a.run_to(ATTACK_AT)
    a.c.planner.proc.send_signal(signal.SIGKILL)
    a.c.planner.proc.wait()
    procs.all.remove(a.c.planner)
    # what the killed planner sent may still be in flight: set-points and states are told
    # apart by their source timestamps, never counted
    t_dead_ns = time.time_ns()
    seen = Recorder(ros.node("restart_observer"),
                    {"/tool/command": PoseStamped, "/shaping/planner_state": (String, True)})
    restart = write_params(tmp_path / "restart.yaml", a.cell, planner={"autostart": True})
    again = procs("planner", "--ros-args", "--params-file", str(restart),
                  "-p", "use_sim_time:=true")

    def decided():
        mine = seen.published_after("/shaping/planner_state", t_dead_ns)
        return mine[-1].data if mine and mine[-1].data in ("tool_away", "holding") else None
    a.c.wait(decided, 60.0, "the new planner to refuse the autostart")
    # the new planner has decided; a set-point it sent would reach us within this window
    n = len(a.diag["/diagnostics"])
    t_end = time.monotonic() + 2.0
    a.c.wait(lambda: time.monotonic() > t_end and len(a.diag["/diagnostics"]) > n, 20.0,
             "2 s more of the simulator's diagnostics")
    assert seen.published_after("/tool/command", t_dead_ns) == []
    text = again.text()
    if decided() == "holding":     # the cell latched an abort meanwhile: a refusal too
        reasons = a.aborts()
        print(f"\nrestarted planner holds on a latched abort: {reasons}")
        assert reasons, text[-3000:]
    else:
        assert "neither at home nor at the plan's start" in text, text[-3000:]
    assert "starting the plan" not in text
    a.check(float(a.sim_values()["F_max"]))
    a.stop()
