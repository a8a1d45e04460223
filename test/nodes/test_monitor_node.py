"""The monitor node in-process, fed by a fake cell over DDS (safety principles 1-3)."""
from __future__ import annotations

import math
import time

import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from std_msgs.msg import String, UInt64  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from rheo_shaping.nodes import messages as m  # noqa: E402

from _support.rigs import F_BREAK, FakeCell, get_ready, listen, make_monitor  # noqa: E402
from _support.ros import Recorder  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
from rheo_shaping.units import NS  # noqa: E402


@pytest.fixture
def cell(ros):
    return FakeCell(ros)


def test_ready_heartbeat_and_diagnostics(ros, cell):
    monitor = make_monitor(ros)
    node, rec = listen(ros)
    assert not monitor.ready
    get_ready(ros, monitor, cell)
    ros.spin_until(lambda: rec["/shaping/ready"] and rec.last("/shaping/ready").data, 5.0,
                   "ready heartbeat", every=lambda: cell.publish())
    ros.spin_until(lambda: any(s.name == "monitor: tension" and s.level == DiagnosticStatus.OK
                               for d in rec["/diagnostics"] for s in d.status), 5.0,
                   "OK diagnostics", every=lambda: cell.publish())
    status = [s for d in rec["/diagnostics"]
              for s in d.status if s.level == DiagnosticStatus.OK][-1]
    keys = {kv.key for kv in status.values}
    assert {"tension_max", "safety_factor", "data_age_tensions", "abort_threshold"} <= keys
    assert rec["/shaping/abort"] == []


def test_threshold_abort_latches_and_is_transient_local(ros, cell):
    monitor = make_monitor(ros, trend_abort=False)
    node, rec = listen(ros)
    get_ready(ros, monitor, cell)
    cell.publish(tension=1.01 * monitor.threshold)
    ros.spin_until(lambda: rec["/shaping/abort"], 5.0, "abort")
    reason = rec["/shaping/abort"][0].data
    assert "abort threshold" in reason and "link 2" in reason
    cell.stream(0.3)                                   # good data again: still aborted
    assert monitor.state == "aborted" and not monitor.ready
    assert len(rec["/shaping/abort"]) == 1
    late = Recorder(ros.node("late_joiner"), {"/shaping/abort": (String, True)})
    ros.spin_until(lambda: late["/shaping/abort"], 10.0, "transient-local abort for a late joiner")
    assert late["/shaping/abort"][0].data == reason
    ros.spin_until(lambda: any(s.level == DiagnosticStatus.ERROR for d in rec["/diagnostics"]
                               for s in d.status), 5.0, "ERROR diagnostics")


def test_reset_rearms_and_clears_the_latched_abort(ros, cell):
    monitor = make_monitor(ros, trend_abort=False)
    node, rec = listen(ros)
    get_ready(ros, monitor, cell)
    cell.publish(tension=2 * F_BREAK)
    ros.spin_until(lambda: monitor.state == "aborted", 5.0, "abort")
    client = node.create_client(Trigger, "/monitor/reset")
    ros.spin_until(lambda: client.service_is_ready(), 10.0, "reset service")
    future = client.call_async(Trigger.Request())
    ros.spin_until(future.done, 5.0, "reset response")
    assert future.result().success
    assert monitor.state == "waiting"
    get_ready(ros, monitor, cell)
    late = Recorder(ros.node("late_joiner2"), {"/shaping/abort": (String, True)})
    ros.spin_until(lambda: late.node.count_publishers(
        "/shaping/abort") >= 1, 10.0, "abort publisher")
    cell.stream(0.5)
    assert late["/shaping/abort"] == []               # the old abort is gone


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_tension_aborts(ros, cell, bad):
    monitor = make_monitor(ros)
    node, rec = listen(ros)
    get_ready(ros, monitor, cell)
    cell.publish(tension=[0.1, bad, 0.1])
    ros.spin_until(lambda: rec["/shaping/abort"], 5.0, "abort on non-finite tension")
    assert "non-finite" in rec["/shaping/abort"][0].data


def test_non_finite_contact_tension_aborts(ros, cell):
    monitor = make_monitor(ros)
    get_ready(ros, monitor, cell)
    cell.publish(contact=math.nan)
    ros.spin_until(lambda: monitor.state == "aborted", 5.0, "abort")
    assert "contact" in monitor.abort_reason


def test_stale_data_aborts_on_the_steady_clock_with_frozen_sim_time(ros, cell):
    """Lesson 1: the simulator dies, /clock freezes; the watchdog still fires in time."""
    monitor = make_monitor(ros, max_data_age=0.3, period=0.02)
    get_ready(ros, monitor, cell)
    t_last = time.monotonic()
    took = ros.spin_until(lambda: monitor.state == "aborted", 5.0, "stale abort")
    assert "stale" in monitor.abort_reason
    assert 0.25 <= time.monotonic() - t_last <= 0.3 + 0.7, took


def test_zero_stamp_aborts(ros, cell):
    monitor = make_monitor(ros)
    get_ready(ros, monitor, cell)
    cell.publish(stamp_ns=0)
    ros.spin_until(lambda: monitor.state == "aborted", 5.0, "abort")
    assert "zero header stamp" in monitor.abort_reason


def test_future_stamp_aborts(ros, cell):
    """Samples stamped 1000 s ahead: every one of them (one alone, followed by fresh
    samples, could leave the monitor's keep-last queue unread on a machine at load 16, and
    the test waited in vain)."""
    monitor = make_monitor(ros)
    get_ready(ros, monitor, cell)
    future = cell.t_ns + 1000 * NS
    ros.spin_until(lambda: monitor.state == "aborted", 5.0, "abort",
                   every=lambda: cell.publish(stamp_ns=future))
    assert "future" in monitor.abort_reason


def test_future_stamp_on_sim_time_waits_for_the_clock_then_aborts(ros, cell):
    """A data stamp ahead of the /clock the node has processed so far: no abort while the
    clock catches up (a busy process handles /clock late); still ahead after max_data_age
    of wall time: abort, with the reason."""
    monitor = make_monitor(ros, max_data_age=0.5)
    get_ready(ros, monitor, cell)
    # the data run 2.4 s of simulated time ahead of the clock, then the clock catches up
    lagging = cell.t_ns
    cell.t_ns += int(2.4 * NS)
    ahead = cell.t_ns
    cell.clock.publish(m.clock_msg(lagging))
    ros.spin_for(0.1)
    cell.profile.publish(m.profile_msg([[0.01, 0.05]], ahead))
    ros.spin_for(0.2)
    assert monitor.state == "ready"                  # held back, not judged yet
    cell.stream(1.0)                                 # the clock catches up: every stamp on time
    assert monitor.state == "ready", monitor.abort_reason
    # a stamp 1000 s ahead that the clock does not reach
    t_bad = time.monotonic()
    cell.profile.publish(m.profile_msg([[0.01, 0.05]], cell.t_ns + 1000 * NS))
    ros.spin_until(lambda: monitor.state == "aborted", 5.0, "abort", every=lambda: cell.publish())
    took = time.monotonic() - t_bad
    assert "future" in monitor.abort_reason
    assert 0.5 <= took <= 0.5 + 0.05 + 0.5, took      # max_data_age + one period (+ scheduling)


def test_rising_trend_aborts_before_the_threshold(ros, cell):
    monitor = make_monitor(ros, trend_abort=True, trend_window=0.5, stop_time=1.0, detect_time=0.1)
    get_ready(ros, monitor, cell)
    F = 0.2
    while monitor.state != "aborted":
        F += 0.4 * 0.05                                # 0.4 N/s of simulated time
        assert F < monitor.threshold, "the threshold was reached before the trend aborted"
        cell.publish(tension=F, dt=0.05)
        ros.spin_for(0.02)
    assert "trend" in monitor.abort_reason
    assert F + 0.4 * 1.1 >= monitor.threshold - 0.03   # it fired about one horizon ahead


def test_no_data_is_not_ready_and_aborts_after_startup_timeout(ros, cell):
    monitor = make_monitor(ros, startup_timeout=1.0)
    node, rec = listen(ros)
    ros.spin_until(lambda: rec["/shaping/ready"], 5.0, "heartbeat")
    assert not any(msg.data for msg in rec["/shaping/ready"])
    ros.spin_until(lambda: monitor.state == "aborted", 5.0, "startup timeout abort")
    assert "not ready within startup_timeout" in monitor.abort_reason
    assert not any(msg.data for msg in rec["/shaping/ready"])


def test_old_stamps_abort_once_ready(ros, cell):
    monitor = make_monitor(ros, max_stamp_age=1.0)
    get_ready(ros, monitor, cell)
    cell.publish(stamp_ns=cell.t_ns - 5 * NS)
    ros.spin_until(lambda: monitor.state == "aborted", 5.0, "abort")
    assert "old" in monitor.abort_reason and "max_stamp_age" in monitor.abort_reason


def test_acknowledges_each_judged_sample_by_its_sequence_number(ros, cell):
    """/shaping/checked carries the DDS sequence number of the newest /sheet/tensions sample
    judged (the writer's n-th sample is n), on each sample and again every period."""
    monitor = make_monitor(ros)
    node = ros.node("ack_listener")
    rec = Recorder(node, {"/shaping/checked": UInt64})
    get_ready(ros, monitor, cell)
    for _ in range(7):
        cell.publish()
    ros.spin_until(lambda: rec["/shaping/checked"] and rec.last("/shaping/checked").data
                   == cell.sent, 10.0, f"the acknowledgement of sample {cell.sent}")
    n = len(rec["/shaping/checked"])
    ros.spin_until(lambda: len(rec["/shaping/checked"]) >= n + 3, 10.0, "repeated every period")
    assert {a.data for a in rec["/shaping/checked"][n:]} == {cell.sent}
    assert monitor.state == "ready"


def test_after_an_abort_acknowledgements_wait_for_the_planner_to_stop(ros, cell):
    """The sample that aborts is acknowledged only once /shaping/planner_state shows the
    planner off its plan: a simulator faster than real time stands still meanwhile."""
    monitor = make_monitor(ros, trend_abort=False, abort_hold=30.0)
    node = ros.node("planner")      # the monitor takes the planner's state from no other node
    state = node.create_publisher(String, "/shaping/planner_state", LATCHED)
    rec = Recorder(node, {"/shaping/checked": UInt64, "/shaping/abort": (String, True)})
    state.publish(String(data="running"))
    ros.spin_until(lambda: monitor.acks.planner_state == "running", 10.0, "the planner's state")
    get_ready(ros, monitor, cell)
    ros.spin_until(lambda: rec["/shaping/checked"] and rec.last("/shaping/checked").data
                   == cell.sent, 10.0, "every sample acknowledged")
    before = cell.sent
    cell.publish(tension=1.01 * monitor.threshold)
    ros.spin_until(lambda: rec["/shaping/abort"], 5.0, "abort")
    n = len(rec["/shaping/checked"])
    ros.spin_until(lambda: len(rec["/shaping/checked"]) >= n + 5, 10.0, "5 more periods")
    assert {a.data for a in rec["/shaping/checked"]} <= set(range(1, before + 1))
    state.publish(String(data="stopping"))
    ros.spin_until(lambda: rec.last("/shaping/checked").data == before + 1, 10.0,
                   "the aborting sample acknowledged once the planner stops")
