"""The simulator node in-process: topics and their contract (docs/interfaces.md), /clock,
following the set-points, lockstep, reset, the hold before the first set-point and the
wait for the monitor's acknowledgements."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseArray, PoseStamped, WrenchStamped  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Float64, Float64MultiArray, UInt64  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from rheo_shaping.nodes import messages as m  # noqa: E402
from rheo_shaping.nodes.simulator import SimulatorNode  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.planning.scenarios import movement_scenario  # noqa: E402
from rheo_shaping.sheet.simulation import Simulation  # noqa: E402

from _support.ros import Recorder, wait_for_publishers, wait_for_subscribers  # noqa: E402
from rheo_shaping.units import NS  # noqa: E402

TOPICS = {"/sheet/profile": PoseArray, "/sheet/tensions": Float64MultiArray,
          "/sheet/contact_tension": Float64, "/tool/pose": PoseStamped,
          "/tool/wrench": WrenchStamped, "/sheet/markers": MarkerArray,
          "/diagnostics": DiagnosticArray}


def make_sim(ros, **settings):
    overrides = [Parameter(k, value=v) for k, v in settings.items()]
    return ros.add(SimulatorNode(context=ros.context, parameter_overrides=overrides))


def listen(ros, clock=False):
    node = ros.node("sim_listener")
    topics = dict(TOPICS)
    rec = Recorder(node, topics)
    if clock:
        rec.add("/clock", Clock, QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    wait_for_publishers(ros, node, list(topics))
    return node, rec


def test_topics_follow_the_contract_on_simulated_time(ros):
    cell = CellParams()
    sim = make_sim(ros, real_time_factor=10.0, step_period=0.01)
    node, rec = listen(ros, clock=True)
    ros.spin_until(lambda: len(rec["/sheet/tensions"]) >= 5 and rec["/sheet/markers"]
                   and rec["/diagnostics"] and rec["/clock"], 15.0, "state messages")
    profile = rec.last("/sheet/profile")
    assert profile.header.frame_id == "cake" and len(profile.poses) == cell.sheet.n_masses
    assert all(p.position.y == 0.0 for p in profile.poses)
    tensions = rec.last("/sheet/tensions")
    assert tensions.layout.dim[0].label == "link"
    assert tensions.layout.dim[0].size == len(tensions.data) == cell.sheet.n_masses + 1
    # tool at its start, no contact
    assert rec.last("/sheet/contact_tension").data == 0.0
    start = movement_scenario(cell).start
    assert m.pose_xz(rec.last("/tool/pose")) == pytest.approx(start)
    assert rec.last("/tool/wrench").header.frame_id == "cake"
    # Before the first set-point the settled sheet waits at process time 0 (offline start).
    ref = Simulation(cell, tool_start=start)
    assert np.allclose(m.profile_points(profile), ref.state.x, atol=1e-12)
    assert np.allclose(tensions.data, ref.state.tension, atol=1e-12)
    # /clock leads the published state by one step; stamps are simulated time, never zero,
    # and held (one step's) until the first set-point.
    stamps = [m.stamp_ns(p.header.stamp) for p in rec["/sheet/profile"]]
    assert set(stamps) == {sim.timeline.dt_ns}
    lead = m.stamp_ns(rec["/clock"][0].clock) - sim.timeline.dt_ns
    ros.spin_until(lambda: lead in [m.stamp_ns(p.header.stamp) for p in rec["/sheet/profile"]],
                   5.0, "the state one step behind /clock")
    ns = {mk.ns for mk in rec.last("/sheet/markers").markers}
    assert {"sheet", "tool", "cake"} <= ns
    assert not sim.started


def test_real_time_factor_one_publishes_no_clock(ros):
    make_sim(ros, real_time_factor=1.0, step_period=0.02)
    node, rec = listen(ros)
    ros.spin_until(lambda: len(rec["/sheet/profile"]) >= 3, 10.0, "profiles")
    assert node.count_publishers("/clock") == 0
    stamp = m.stamp_ns(rec.last("/sheet/profile").header.stamp)
    assert abs(stamp - node.get_clock().now().nanoseconds) < 5 * NS   # wall-clock stamps


def test_follows_set_points_in_lockstep_and_resets(ros):
    cell = CellParams()
    sim = make_sim(ros, real_time_factor=10.0, step_period=0.01)
    node, rec = listen(ros)
    cmd = node.create_publisher(PoseStamped, "/tool/command", 100)
    wait_for_subscribers(ros, cmd)
    start = np.array(movement_scenario(cell).start)
    ros.spin_until(lambda: sim.timeline.t_ns > 0, 10.0, "simulated time")
    t0 = sim.timeline.t_ns + sim.timeline.dt_ns
    path = lambda t: start + np.array([0.0, -1e-3]) * t          # noqa: E731  1 mm/s down
    sent = [0]

    def stream():      # set-points every 20 ms of simulated time up to the simulator's clock
        clock = sim.timeline.t_ns + sim.timeline.dt_ns
        while t0 + sent[0] * int(0.02 * NS) <= clock:
            t = sent[0] * 0.02
            cmd.publish(m.pose_msg(path(t), t0 + sent[0] * int(0.02 * NS)))
            sent[0] += 1

    ros.spin_until(lambda: sim.started and sim.process_time >= 3.0, 20.0, "3 s of process",
                   every=stream)
    assert sim.sim.state.tool == pytest.approx(path(sim.process_time), abs=1e-12)
    poses = [(m.stamp_ns(p.header.stamp), m.pose_xz(p)) for p in rec["/tool/pose"]]
    after = [t for t, _ in poses if t >= t0]
    assert len(after) > 10 and np.all(np.diff(after) > 0)     # one state per step once started
    for t, xz in poses:
        if t >= t0:
            assert np.allclose(xz, path((t - t0) / NS), atol=1e-12)
    client = node.create_client(Trigger, "/simulator/reset")
    ros.spin_until(client.service_is_ready, 10.0, "reset service")
    future = client.call_async(Trigger.Request())
    ros.spin_until(future.done, 5.0, "reset")
    assert future.result().success
    assert not sim.started and sim.process_time == 0.0
    assert sim.sim.state.tool == pytest.approx(start)


def test_process_figures_at_process_time(ros):
    """A short process (5 s) of a still tool: the node's figures equal the core's."""
    sim = make_sim(ros, **{"real_time_factor": 20.0, "step_period": 0.01,
                           "movement.process_time": 5.0, "start_on_command": False})
    ros.spin_until(lambda: sim.summary is not None, 20.0, "process end")
    cell = sim.cell
    ref = Simulation(cell, tool_start=movement_scenario(cell).start)
    peak = max(float(np.max(ref.state.tension)), 0.0)
    ticks = []
    t = 0.0
    while t < 5.0 - 1e-9:       # the node's steps: 1 s of simulated time each (20 x 0.01 x 5)
        t = min(t + 0.2, 5.0)
        ref.advance_to(t, ref.state.tool, on_step=lambda s: ticks.append(float(np.max(s.tension))))
    assert sim.summary.delta == pytest.approx(ref.delta(), abs=1e-6)
    assert sim.summary.F_max == pytest.approx(max(ticks + [peak]), rel=0.02)


def test_clock_holds_until_the_first_set_point(ros):
    """Lockstep on simulated time: after its first step /clock stands still until the first
    /tool/command, so a plan whose first set-points arrive late (a lossy link) starts where
    the simulation is; the clock and the unchanged state keep coming meanwhile (the monitor's
    data)."""
    sim = make_sim(ros, real_time_factor=10.0, step_period=0.01)
    node, rec = listen(ros, clock=True)
    ros.spin_until(lambda: sim.timeline.clock_holds >= 20, 20.0, "20 held steps")
    n = len(rec["/sheet/tensions"])
    ros.spin_until(lambda: len(rec["/sheet/tensions"]) >= n + 10, 10.0, "tensions while held")
    dt = sim.timeline.dt_ns
    assert not sim.started and sim.timeline.t_ns == dt           # one step, then the hold
    clock = {m.stamp_ns(c.clock) for c in rec["/clock"]}
    assert clock == {2 * sim.timeline.dt_ns}                               # one step ahead, held
    assert {m.stamp_ns(p.header.stamp) for p in rec["/sheet/profile"]} == {sim.timeline.dt_ns}
    cmd = node.create_publisher(PoseStamped, "/tool/command", 100)
    wait_for_subscribers(ros, cmd)
    start = np.array(movement_scenario(sim.cell).start)
    t0 = 2 * sim.timeline.dt_ns
    cmd.publish(m.pose_msg(start, t0))
    ros.spin_until(lambda: sim.timeline.t_ns >= t0 + 5 * dt, 20.0, "steps after the start")
    assert sim.process_offset_ns == t0                 # process time 0 = the plan's start


def test_waits_for_the_monitors_acknowledgements(ros):
    """On simulated time the simulator publishes at most monitor_lead tension samples beyond
    the newest the monitor acknowledged (/shaping/checked); without acknowledgements for
    command_timeout it runs on."""
    sim = make_sim(ros, real_time_factor=10.0, step_period=0.01, start_on_command=False,
                   publish_period=0.0, monitor_lead=3, command_timeout=0.2)
    node = ros.node("monitor")             # the simulator takes acknowledgements from no other
    ack = node.create_publisher(UInt64, "/shaping/checked", 1)
    wait_for_subscribers(ros, ack)
    ros.spin_until(lambda: sim._lead.sent > 3, 20.0, "tension samples")
    nothing = lambda: ack.publish(UInt64(data=0))              # noqa: E731  fresh, none judged
    ros.spin_until(lambda: sim.monitor_waits >= 5, 10.0, "held for the monitor", every=nothing)
    held = sim._lead.sent
    w = sim.monitor_waits
    ros.spin_until(lambda: sim.monitor_waits >= w + 20, 10.0, "still held", every=nothing)
    assert sim._lead.sent == held
    judged = lambda: ack.publish(UInt64(data=held))            # noqa: E731
    ros.spin_until(lambda: sim._lead.sent == held + 3, 10.0, "3 more samples", every=judged)
    w = sim.monitor_waits
    ros.spin_until(lambda: sim.monitor_waits >= w + 20, 10.0, "held again", every=judged)
    assert sim._lead.sent == held + 3
    ros.spin_until(lambda: sim._lead.sent > held + 20, 10.0, "running on without a monitor")


def test_while_it_waits_for_the_first_set_point_the_state_goes_out_a_few_times_a_second(ros):
    """/clock holds before the first set-point; the unchanged state is re-published every
    HOLD_REPUBLISH (0.1 s) of wall time for the monitor's freshness, not every step (it once
    sent 2,429 identical profiles in 25 s at 100 steps/s)."""
    import time

    from rheo_shaping.sheet.setpoints import HOLD_REPUBLISH
    sim = make_sim(ros, real_time_factor=10.0, step_period=0.01, camera=False)
    node, rec = listen(ros)
    ros.spin_until(lambda: sim.timeline.clock_holds > 0, 20.0, "the hold for the first set-point")
    n0, holds0, t0 = len(rec["/sheet/profile"]), sim.timeline.clock_holds, time.monotonic()
    ros.spin_for(3.0)
    wall = time.monotonic() - t0
    profiles, steps = len(rec["/sheet/profile"]) - n0, sim.timeline.clock_holds - holds0
    print(f"\nwaiting {wall:.2f} s: {steps} held steps, {profiles} profiles")
    assert not sim.started
    assert profiles <= wall / HOLD_REPUBLISH + 2            # not one per held step
    assert profiles >= wall / 0.5 - 1                        # fresh for a 0.5 s max_data_age
    assert steps > 2 * profiles
