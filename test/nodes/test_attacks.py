"""Rogue, frozen and lying inputs against the three node processes (docs/safety.md).

The cell runs a "tear plan" (test/_support/attacks.py).  Each test attacks the running
cell as an outsider could on the same ROS domain (a second commander, a forged /clock, a
frozen monitor, a twin node, lying tension data, a parameter slip, a spoofed heartbeat, the
planner killed with SIGKILL and restarted) and checks what matters: the largest tension
the simulator computed stays below the abort threshold plus what the stopping budget
allows and below F_break, the reason is named, and no process prints a traceback.
"""
from __future__ import annotations

import signal
import time

import pytest

pytest.importorskip("rclpy")

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Bool, String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from rheo_shaping.nodes import messages as m  # noqa: E402
from rheo_shaping.units import NS  # noqa: E402

from _support.attacks import (ATTACK_AT, RTF, STEP, Attacked, lie_until_abort,  # noqa: E402
                              off_plan, publish_for, rogue_tensions, tear_cell)
from _support.cells import write_params  # noqa: E402
from _support.ros import Recorder  # noqa: E402


@pytest.mark.parametrize("after_abort", [False, True], ids=["during_run", "after_abort"])
def test_a_second_commander_is_refused_and_the_tool_holds(ros, procs, tmp_path, after_abort):
    a = Attacked(ros, procs, tmp_path)
    a.run_to(ATTACK_AT)
    if after_abort:                 # the cell already stopped: the rogue must not move it
        lie_until_abort(a, ros)                 # lying data: the monitor aborts
    rogue = ros.node("rogue_commander").create_publisher(PoseStamped, "/tool/command", 10)
    pose = a.c.rec.last("/tool/pose")
    x, z = m.pose_xz(pose)
    t_rogue = a.process_time()
    # a plausible-looking set-point 35 mm back along x, stamped like the planner's
    publish_for(ros, rogue, lambda: m.pose_msg((x - 0.035, z), m.stamp_ns(
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
        off = off_plan(a, held_at, t_rogue)
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

    def lost() -> dict:              # the simulator's first report of the hold, as it was
        for msg in a.diag["/diagnostics"]:
            for st in msg.status:
                if st.name == "simulator: sheet" and "monitor lost" in st.message:
                    return {kv.key: kv.value for kv in st.values}
        return {}
    try:
        a.c.wait(lambda: bool(lost()), 20.0, "the simulator to see the frozen monitor")
        held = lost()
        seen = time.monotonic() - t_freeze
        F_max = a.peak_after_hold()
        # process time from the freeze to the hold (a held tool's sheet steps on, settling:
        # read later, on a machine at load 16, it had run 67.5 s further)
        moved = float(held["process_time"]) - t_sim
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
    # (a refusal of the newcomer itself, on the cell's latched abort, is a refusal too; on a
    # machine at load 16 the twin yielded before this client had matched its service: no
    # answer at all, and the one pass below is what is left to check)
    assert all(r.success or "already started" in r.message
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
    # one pass, the first one: one run's start (its header stamp; the closed loop publishes
    # each re-plan of that run with the same stamp)
    starts = {m.stamp_ns(p.header.stamp) for p in a.c.rec["/tool/planned_trajectory"]}
    assert len(starts) == 1, sorted(starts)
    if reasons:
        a.check(a.peak_after_hold())
    a.stop()


@pytest.mark.parametrize("rate_hz", [20, 10_000], ids=["lying", "flood"])
def test_a_second_writer_of_the_tensions_aborts_with_its_name(ros, procs, tmp_path, rate_hz):
    """A rogue writer of /sheet/tensions, lying (one link, 0.1 N) or flooding at 10 kHz
    (it pushed the simulator's samples out of the monitor's 10-deep queue and the monitor
    acknowledged the rogue's sequence numbers: 5 tears in 6 runs): the monitor takes the
    tensions from its simulator only, and aborts naming the rogue.  What the monitor does
    with lying values of its own simulator is tested on its core (test_monitor_core)."""
    a = Attacked(ros, procs, tmp_path)
    a.run_to(ATTACK_AT)
    rogue = rogue_tensions(a, ros)
    msg = m.tensions_msg([0.1])
    k = len(a.aborts())
    t_end = time.monotonic() + 20.0
    while len(a.aborts()) == k and time.monotonic() < t_end:
        for _ in range(max(1, rate_hz // 100)):         # a burst every 10 ms
            rogue.publish(msg)
        ros.spin_for(0.01)
    reasons = " | ".join(a.aborts())
    # the rogue is named, unless the tear plan met the threshold first (a busy machine)
    assert ("a second writer of /sheet/tensions: /rogue_tensions" in reasons
            or "reached the abort threshold" in a.aborts()[0]), reasons
    assert "has 1 links" not in reasons                  # the rogue's samples never judged
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
    lie_until_abort(a, ros)
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
    publish_for(ros, spoof, lambda: Bool(data=True), 3.0, period=0.05)
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
