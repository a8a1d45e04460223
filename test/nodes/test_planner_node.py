"""The planner node in-process on a simulated clock the test drives: interlock,
streaming of the core's plan, the jerk-limited abort stop, latching and reset."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rclpy")

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Bool, String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402

from rheo_shaping.nodes import messages as m  # noqa: E402
from rheo_shaping.nodes.planner import PlannerNode  # noqa: E402
from rheo_shaping.params.fingerprint import cell_message  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.params.schema import ParameterError  # noqa: E402
from rheo_shaping.planning.movement import movement_plan  # noqa: E402

from _support.ros import Recorder, executed, motion_bounds, wait_for_subscribers  # noqa: E402
from rheo_shaping.units import NS  # noqa: E402

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Bench:
    """The planner with a fake monitor (heartbeat, abort) and a clock the test advances."""

    def __init__(self, ros, **settings):
        self.ros = ros
        self.node = ros.node("planner_bench")
        self.clock = self.node.create_publisher(Clock, "/clock", 1)
        # the heartbeat from a node named as the monitor (the planner takes it from no other)
        self.ready = ros.node("monitor").create_publisher(Bool, "/shaping/ready", 1)
        self.abort = self.node.create_publisher(String, "/shaping/abort", LATCHED)
        self.rec = Recorder(self.node, {"/tool/command": PoseStamped,
                                        "/tool/planned_trajectory": (JointTrajectory, True),
                                        "/shaping/planner_state": (String, True)})
        self.t_ns = 5 * NS
        overrides = [Parameter("use_sim_time", value=True)]
        overrides += [Parameter(k, value=v) for k, v in settings.items()]
        self.planner = ros.add(PlannerNode(context=ros.context, parameter_overrides=overrides))
        self.heartbeat = True
        self.hold_at = None         # [m] (x, z): the tool held there, as a simulator holds it
        # the executed tool pose: a tool that follows the newest set-point at once
        self.pose = self.node.create_publisher(PoseStamped, "/tool/pose", 10)
        self.cell = self.node.create_publisher(String, "/shaping/cell", LATCHED)
        self.cell.publish(String(data=cell_message(self.planner.cell)))
        # the simulator says it follows no planner yet (the planner waits for that)
        self.commander = self.node.create_publisher(String, "/shaping/commander", LATCHED)
        self.commander.publish(String(data=""))
        wait_for_subscribers(ros, self.clock)
        wait_for_subscribers(ros, self.ready)
        wait_for_subscribers(ros, self.pose)

    def tick(self, dt=0.02, spin=0.002):
        self.t_ns += int(round(dt * NS))
        self.clock.publish(m.clock_msg(self.t_ns))
        if self.heartbeat:
            self.ready.publish(Bool(data=True))
        # the tool at the newest set-point, executed one tick behind the clock
        last = self.rec.last("/tool/command")
        xz = m.pose_xz(last) if last is not None else self.planner.plan.start
        xz = xz if self.hold_at is None else self.hold_at
        self.pose.publish(m.pose_msg(xz, self.t_ns - int(round(dt * NS))))
        self.ros.spin_for(spin)

    def run(self, seconds, dt=0.02):
        for _ in range(int(round(seconds / dt))):
            self.tick(dt)

    def until(self, predicate, timeout=20.0, what="", dt=0.02):
        self.ros.spin_until(predicate, timeout, what, every=lambda: self.tick(dt, spin=0.0))

    def drain(self):
        """Spin (clock still) until every set-point the planner published has arrived."""
        target = self.planner._last_cmd_ns
        self.ros.spin_until(lambda: self.rec["/tool/command"] and
                            m.stamp_ns(self.rec["/tool/command"][-1].header.stamp) >= target,
                            10.0, "the planner's set-points")

    def commands(self):
        self.drain()
        return executed(self.rec["/tool/command"])

    def states(self):
        return [s.data for s in self.rec["/shaping/planner_state"]]


def test_interlock_no_motion_until_the_monitor_is_ready(ros):
    b = Bench(ros)
    b.heartbeat = False
    b.until(lambda: b.planner.state != "starting", what="the planner up")
    b.run(1.5)
    assert b.rec["/tool/command"] == []
    assert b.planner.state == "waiting_for_monitor"
    b.heartbeat = True
    b.until(lambda: b.rec["/tool/command"], what="first set-point")
    assert b.planner.state == "running"


def test_streams_the_cores_plan_and_publishes_it_once(ros):
    b = Bench(ros)
    b.until(lambda: b.rec["/tool/planned_trajectory"], what="planned trajectory")
    b.run(3.0)
    [traj] = b.rec["/tool/planned_trajectory"]
    assert list(traj.joint_names) == ["tool_x", "tool_z"] and traj.header.frame_id == "cake"
    t0 = m.stamp_ns(traj.header.stamp)
    plan = movement_plan(CellParams()).plan
    last = traj.points[-1].time_from_start
    assert last.sec + last.nanosec / NS == pytest.approx(plan.duration, abs=1e-6)
    t, p = b.commands()
    assert t[0] == t0 and np.all(np.diff(t) > 0)
    assert np.all(np.diff(t) <= int(0.02 * NS))                 # 50 Hz (and the clock's times)
    expected, _, _ = plan.sample_many((t - t0) / NS)
    assert np.max(np.abs(p - expected)) < 1e-12
    assert all(c.header.frame_id == "cake" for c in b.rec["/tool/command"])


def _check_limits(t_ns, p, v_max, a_max, j_max, rel=1e-6):
    """Speed, acceleration, jerk of the set-points (divided differences) within the limits."""
    v, a, j = motion_bounds(t_ns, p)
    assert v <= v_max * (1 + rel) + 1e-9, (v, v_max)
    assert a <= a_max * (1 + rel) + 1e-6, (a, a_max)
    assert j <= j_max * (1 + rel) + 1e-4, (j, j_max)
    return v, a, j


def test_abort_stops_within_jerk_limits_retracts_and_latches(ros):
    cell = CellParams()
    b = Bench(ros, **{"movement.number": 2, "movement.speed": 5e-3, "retract_speed": 0.01,
                      "retract_accel": 0.01, "retract_jerk": 0.1})
    b.until(lambda: b.rec["/tool/command"], what="start")
    b.run(4.0)                                          # cruising at 5 mm/s
    b.abort.publish(String(data="test abort"))
    b.until(lambda: b.planner.state == "stopping", what="stopping")
    t_abort = b.planner.streamer.abort_time
    rest = b.planner.streamer.rest_time
    b.until(lambda: b.planner.state == "holding", timeout=30.0, what="holding", dt=0.1)
    t, p = b.commands()
    stop = (t >= int(t_abort * NS) - 3 * int(0.02 * NS)) & (t <= int(rest * NS))
    v, a, j = _check_limits(t[stop], p[stop], 5e-3, cell.movement.accel, cell.movement.jerk)
    assert a > 0.5 * cell.movement.accel                     # it did brake hard, within limits
    assert rest - t_abort == pytest.approx(5e-3 / 5e-3 + 5e-3 / 5e-2, rel=1e-3)   # v/a + a/j
    assert np.allclose(p[-1], cell.tool.home, atol=1e-9)     # retracted home, holds
    assert "holding" in b.states() and b.planner.aborted
    n = len(b.rec["/tool/command"])
    b.run(1.0, dt=0.1)                                       # latched: keeps holding at home
    _, p2 = b.commands()
    assert np.allclose(p2[n:], cell.tool.home, atol=1e-12)
    assert b.planner.state == "holding"


def test_lost_monitor_stops_the_tool(ros):
    b = Bench(ros, monitor_timeout=0.3)
    b.until(lambda: b.planner.state == "running", what="running")
    b.run(1.0)
    b.heartbeat = False
    b.until(lambda: b.planner.aborted, timeout=5.0, what="stop on monitor loss")
    assert "monitor lost" in b.planner.abort_reason
    # it stops (a busy machine may have ticked the short stop to its end before this line)
    assert b.planner.state in ("stopping", "retracting", "holding")
    b.until(lambda: b.planner.state == "holding", timeout=30.0, what="holding", dt=0.1)
    b.drain()
    assert {"stopping", "retracting"} & set(b.states()), b.states()


def test_reset_refused_while_moving_then_rearms_with_an_approach(ros):
    home = [0.06, 0.09]                                        # away from the plan's start
    b = Bench(ros, **{"retract_speed": 0.02, "retract_accel": 0.02, "retract_jerk": 0.2,
                      "tool.home": home})
    b.until(lambda: b.planner.state == "running", what="running")
    b.run(1.0)
    # the tool 1 mm along the plan (on a busy machine the set-points may reach the recorder
    # later than 1 s): the approach after the reset then has somewhere to come from

    def along() -> bool:
        last = b.rec.last("/tool/command")
        return last is not None and float(np.hypot(*(np.asarray(m.pose_xz(last))
                                                     - b.planner.plan.start))) > 1e-3
    b.until(along, what="the tool 1 mm along the plan")
    # the simulator holds the tool where the abort finds it (it follows no stop or retract)
    b.hold_at = m.pose_xz(b.rec.last("/tool/command"))
    b.abort.publish(String(data="test abort"))
    b.until(lambda: b.planner.state in ("stopping", "retracting"), what="stopping")
    client = b.node.create_client(Trigger, "/planner/reset")
    ros.spin_until(client.service_is_ready, 10.0, "reset service")
    future = client.call_async(Trigger.Request())
    ros.spin_until(future.done, 5.0, "reset response")
    assert not future.result().success and "moving" in future.result().message
    b.until(lambda: b.planner.state == "holding", timeout=30.0, what="holding", dt=0.1)
    # The abort is still latched on the topic (transient local, the fake monitor was not
    # reset): a reset clears the planner's latch; clear the monitor's first, as the cell does.
    b.node.destroy_publisher(b.abort)
    future = client.call_async(Trigger.Request())
    ros.spin_until(future.done, 5.0, "reset response")
    assert future.result().success, future.result().message
    b.until(lambda: b.planner.state == "running", what="running again")
    plan = b.planner.streamer.plan
    # an approach back to the start from where the tool is measured, not from home where
    # the planner's own retract ended (37 mm away)
    assert plan.segments[0].label == "approach"
    assert np.hypot(*(np.asarray(plan.start) - b.hold_at)) < 1e-9
    assert np.hypot(*(np.asarray(plan.start) - home)) > 0.03


def test_refuses_a_plan_that_pinches_the_sheet(ros):
    cell = CellParams()
    end = (cell.movement.end_2[0] - 3e-3, cell.movement.end_2[1])     # 3 mm deeper: a pinch
    overrides = [Parameter("movement.number", value=2),
                 Parameter("movement.end_2", value=list(end))]
    with pytest.raises(ParameterError, match="pinches the sheet") as exc:
        PlannerNode(context=ros.context, parameter_overrides=overrides)
    assert "clearance_factor" in str(exc.value)
    node = ros.add(PlannerNode(context=ros.context, parameter_overrides=[
        *overrides, Parameter("clearance_factor", value=0.0)]))
    assert node.plan.duration > 0


def test_optimise_d_picks_the_cores_best_d_before_moving(ros):
    from rheo_shaping.planning.choose_d import best_d, d_values
    settings = {"optimise_d": True, "d_min": 0.012, "d_max": 0.017, "d_step": 0.0025,
                "delta_limit": 5e-3}
    node = ros.add(PlannerNode(context=ros.context, parameter_overrides=[
        Parameter(k, value=v) for k, v in settings.items()]))
    want = best_d(CellParams(), d_values(0.012, 0.017, 0.0025), 5e-3)
    assert node.cell_used.movement.d == pytest.approx(want.d)
    cell = node.cell_used
    assert node.plan.start == pytest.approx(movement_plan(cell).plan.start)


def test_starts_only_once_its_set_points_have_a_subscriber(ros):
    """Set-points sent to nobody would make a simulator that matches later join mid-plan:
    with the interlock open and the clock running, the planner waits for a subscriber, and
    the first set-point it gets is the plan's start."""
    node = ros.node("planner_bench_nosub")
    clock = node.create_publisher(Clock, "/clock", 1)
    ready = ros.node("monitor").create_publisher(Bool, "/shaping/ready", 1)
    planner = ros.add(PlannerNode(context=ros.context,
                                  parameter_overrides=[Parameter("use_sim_time", value=True)]))
    pose = node.create_publisher(PoseStamped, "/tool/pose", 10)
    cell = node.create_publisher(String, "/shaping/cell", LATCHED)
    cell.publish(String(data=cell_message(planner.cell)))
    commander = node.create_publisher(String, "/shaping/commander", LATCHED)
    commander.publish(String(data=""))
    wait_for_subscribers(ros, clock)
    wait_for_subscribers(ros, ready)
    t = [5 * NS]

    def tick():
        t[0] += int(0.02 * NS)
        clock.publish(m.clock_msg(t[0]))
        ready.publish(Bool(data=True))
        pose.publish(m.pose_msg(planner.plan.start, t[0] - int(0.02 * NS)))
    ros.spin_until(lambda: planner.state == "waiting_for_subscriber", 20.0,
                   "waiting_for_subscriber", every=tick)
    t_wait = t[0]
    ros.spin_until(lambda: t[0] >= t_wait + 2 * NS, 20.0, "2 s of clock", every=tick)
    assert planner.state == "waiting_for_subscriber" and planner.streamer is None
    rec = Recorder(node, {"/tool/command": PoseStamped})
    ros.spin_until(lambda: rec["/tool/command"], 20.0, "the first set-point", every=tick)
    first = rec["/tool/command"][0]
    assert m.stamp_ns(first.header.stamp) == planner._t0_ns
    assert m.pose_xz(first) == pytest.approx(planner.plan.sample(0.0)[0], abs=1e-9)
