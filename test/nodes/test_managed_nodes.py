"""The managed (lifecycle) nodes in-process (rheo_shaping/nodes/managed.py): each state's
entities and timers, cleanup and a second configure, the planner's activation behind the
monitor's interlock, and what deactivating each node does to a running cell."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest

pytest.importorskip("rclpy")

from lifecycle_msgs.msg import State  # noqa: E402
from rclpy.lifecycle import TransitionCallbackReturn  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from rheo_shaping.nodes import messages as m  # noqa: E402
from rheo_shaping.nodes import topics as T  # noqa: E402
from rheo_shaping.nodes.managed import (ManagedMonitorNode, ManagedPlannerNode,  # noqa: E402
                                        ManagedSimulatorNode)

from rheo_shaping.units import NS  # noqa: E402
from rheo_shaping.planning.run_state import reset_refusal  # noqa: E402

from _support.ros import Recorder, executed  # noqa: E402

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE
QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


#: One thread of this test process runs all three nodes and the observer: on a busy machine
#: a stall of it of over 0.5 s is, by design, stale data for the monitor (a missed QoS
#: deadline) and a lost monitor for the simulator and the planner (seen in a full colcon
#: test at load ~17: the run aborted as it started).  These tests are about the lifecycle,
#: so the data-age limits are 5 s here; test_faults.py and test_attacks.py test the limits.
PATIENT = {"simulator": {"monitor_timeout": 5.0}, "monitor": {"max_data_age": 5.0},
           "planner": {"monitor_timeout": 5.0}}


def _overrides(node: str, **more) -> list:
    return [Parameter(k, value=v) for k, v in {**PATIENT[node], **more}.items()]


def _cell(ros):
    kw = dict(context=ros.context)
    sim = ros.add(ManagedSimulatorNode(
        parameter_overrides=_overrides("simulator", real_time_factor=10.0), **kw))
    monitor = ros.add(ManagedMonitorNode(
        parameter_overrides=_overrides("monitor", use_sim_time=True), **kw))
    planner = ros.add(ManagedPlannerNode(
        parameter_overrides=_overrides("planner", use_sim_time=True), **kw))
    return sim, monitor, planner


def _label(node) -> str:
    return node.lifecycle_state


def _own_topics(node) -> set[str]:
    return {p.topic_name for p in node.publishers} - {"/rosout", "/parameter_events"}


def test_unconfigured_nodes_have_only_their_lifecycle_and_heartbeat(ros):
    nodes = _cell(ros)
    observer = ros.node("beats")
    rec = Recorder(observer, {f"/{n.get_name()}/heartbeat": T.HEARTBEAT.type for n in nodes})
    ros.spin_until(lambda: all(rec[t] for t in rec.msgs), 20.0, "a heartbeat of each node")
    for node in nodes:
        name = node.get_name()
        assert _label(node) == "unconfigured"
        # (and rcl's /NAME/transition_event, which rclpy does not list)
        assert _own_topics(node) == {f"/{name}/heartbeat"}, name
        assert not node.has_parameter("material.k1")
        beat = json.loads(rec.last(f"/{name}/heartbeat").data)
        assert beat["state"] == "unconfigured" and beat["transitions"] == 0


def test_configure_builds_the_plain_node_with_its_timers_stopped_and_cleanup_undoes_it(ros):
    sim, monitor, planner = _cell(ros)
    before = {n.get_name(): _own_topics(n) for n in (sim, monitor, planner)}
    observer = ros.node("watch")
    rec = Recorder(observer, {"/shaping/ready": T.READY.type, "/clock": T.CLOCK.type})
    for node in (sim, monitor, planner):
        assert node.trigger_configure() == SUCCESS
        assert _label(node) == "inactive"
        assert node.has_parameter("material.k1")
    assert "/sheet/tensions" in _own_topics(sim) and "/shaping/ready" in _own_topics(monitor)
    # inactive: the simulator does not step (no /clock), the monitor does not beat
    ros.spin_for(1.0)
    assert rec["/clock"] == [] and rec["/shaping/ready"] == []
    assert all(t.is_canceled() for n in (sim, monitor, planner) for t in n._work_timers)
    for node in (sim, monitor, planner):
        assert node.trigger_cleanup() == SUCCESS
        assert _label(node) == "unconfigured"
        assert _own_topics(node) == before[node.get_name()], node.get_name()
        assert not node.has_parameter("material.k1")
    # a second configure reads the parameters again (the -p overrides hold)
    for node in (sim, monitor, planner):
        assert node.trigger_configure() == SUCCESS, node.get_name()
    assert sim.settings.real_time_factor == 10.0
    assert monitor.get_parameter("use_sim_time").value is True
    assert sim.trigger_activate() == SUCCESS
    ros.spin_until(lambda: rec["/clock"], 20.0, "/clock from the activated simulator")


def test_a_refused_configure_stays_unconfigured_and_leaves_nothing_behind(ros):
    node = ros.add(ManagedMonitorNode(context=ros.context, parameter_overrides=[
        Parameter("period", value=5.0)]))         # valid: (0, 1] s
    before = _own_topics(node)
    assert node.trigger_configure() == FAILURE
    assert _label(node) == "unconfigured"
    assert _own_topics(node) == before and not node.has_parameter("material.k1")


def test_the_planner_activates_only_behind_a_ready_monitor_and_a_run_stops_on_deactivate(ros):
    sim, monitor, planner = _cell(ros)
    observer = ros.node("watch")
    rec = Recorder(observer, {"/tool/command": T.TOOL_COMMAND.type,
                              "/shaping/abort": (T.ABORT.type, True),
                              "/shaping/planner_state": (T.PLANNER_STATE.type, True),
                              "/shaping/ready": T.READY.type})
    for node in (sim, monitor, planner):
        assert node.trigger_configure() == SUCCESS
    # no monitor heartbeat at all: refused, still inactive
    assert planner.trigger_activate() == FAILURE and _label(planner) == "inactive"
    assert sim.trigger_activate() == SUCCESS and monitor.trigger_activate() == SUCCESS
    ros.spin_until(lambda: planner._ready, 30.0, "the monitor ready, as the planner sees it")
    assert planner.trigger_activate() == SUCCESS
    ros.spin_until(lambda: planner.state == "running" and len(rec["/tool/command"]) > 20, 60.0,
                   "the planner running")
    assert planner.trigger_deactivate() == SUCCESS
    deactivated = time.time_ns()
    assert planner.abort_reason == "planner: deactivated (lifecycle)"
    assert planner.state == "inactive"
    st = planner.streamer
    # at rest where the stop ends, no retract begun (an inactive planner streams none): the
    # recovery's ~/reset is taken (else refused, "the tool is moving (retracting)", every
    # time: seen in test_lifecycle.py's pause and resume under stress-ng --cpu 8)
    assert st.state == "holding"
    assert reset_refusal(st.state) == ""
    end = int(round((st.abort_time + st.stop_plan.duration) * NS))
    # the stop was sent to its end, at rest, with the deactivation; nothing after it
    ros.spin_until(lambda: any(m.stamp_ns(c.header.stamp) == end for c in rec["/tool/command"]),
                   10.0, "the stop's last set-point")
    t, xz = executed(rec["/tool/command"])
    assert t[-1] == end
    assert np.array_equal(xz[-1], st.setpoint(end / NS)[0])
    assert np.linalg.norm(st.setpoint(end / NS)[1]) == pytest.approx(0.0, abs=1e-12)
    ros.spin_for(1.0)
    assert rec.published_after("/tool/command", deactivated) == []
    ros.spin_until(lambda: rec.last("/shaping/planner_state").data == "inactive", 10.0,
                   "planner_state inactive")

    # the monitor deactivated: ready false once, then no beat
    assert monitor.trigger_deactivate() == SUCCESS
    ros.spin_until(lambda: rec.last("/shaping/ready").data is False, 10.0, "ready false")
    k = len(rec["/shaping/ready"])
    ros.spin_for(0.5)
    assert len(rec["/shaping/ready"]) == k           # (one publisher: in order, none after)

    # the simulator deactivated: the tool holds, the reason on /shaping/abort
    assert sim.trigger_deactivate() == SUCCESS
    assert sim.gate.held.startswith("deactivated (lifecycle)")
    ros.spin_until(lambda: rec["/shaping/abort"] and "deactivated" in
                   rec.last("/shaping/abort").data, 10.0, "the simulator's hold on abort")
    assert rec.last("/shaping/abort").data.startswith("simulator: deactivated (lifecycle)")
    for node in (sim, monitor, planner):
        assert node.trigger_shutdown() == SUCCESS
        assert node._state_machine.current_state[0] == State.PRIMARY_STATE_FINALIZED


def test_a_planner_deactivated_while_it_retracts_after_an_abort_can_be_reset(ros):
    """An abort, its stop, then the retract: deactivated then (the manager's failure while
    the planner retracts), the retract is stopped too and sent to its end at rest; the
    stream holds, so the recovery's ~/reset is taken (it stayed `retracting` while inactive
    and refused 40 resets: seen in test_lifecycle.py's recovery at load 7-10)."""
    sim, monitor, planner = _cell(ros)
    for node in (sim, monitor, planner):
        assert node.trigger_configure() == SUCCESS
    assert sim.trigger_activate() == SUCCESS and monitor.trigger_activate() == SUCCESS
    ros.spin_until(lambda: planner._ready, 30.0, "the monitor ready, as the planner sees it")
    assert planner.trigger_activate() == SUCCESS
    ros.spin_until(lambda: planner.state == "running" and planner.grid.last_ns
                   > planner.grid.t0_ns + 30 * NS, 60.0, "30 s of the run (the tool away)")
    monitor._abort("monitor: a test's abort")
    ros.spin_until(lambda: planner.streamer.state == "retracting", 60.0, "the retract")
    assert planner.trigger_deactivate() == SUCCESS
    st = planner.streamer
    assert st.state in ("stopping", "holding") and planner.state == "inactive"
    end = st.abort_time + st.stop_plan.duration
    assert np.linalg.norm(st.setpoint(end)[1]) == pytest.approx(0.0, abs=1e-12)
    assert st.state == "holding"
    reply = planner._on_reset(Trigger.Request(), Trigger.Response())
    assert reply.success, reply.message
    for node in (sim, monitor, planner):
        assert node.trigger_shutdown() == SUCCESS


def test_shutdown_from_active_stops_first(ros):
    sim = ros.add(ManagedSimulatorNode(
        context=ros.context, parameter_overrides=[Parameter("real_time_factor", value=10.0)]))
    assert sim.trigger_configure() == SUCCESS and sim.trigger_activate() == SUCCESS
    assert sim.trigger_shutdown() == SUCCESS
    assert sim.lifecycle_state == "finalized"
    assert sim._transitions == 3                   # configure, activate, shutdown
    assert not sim.has_parameter("material.k1")    # destroyed after the hold below
    assert sim.gate.held.startswith("deactivated (lifecycle)")
