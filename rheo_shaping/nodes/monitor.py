"""The ``monitor`` node: aborts the shaping before the sheet tears, and on any doubt.

Inputs: ``/sheet/tensions`` and ``/sheet/contact_tension`` (the tensions),
``/sheet/profile`` and ``/tool/wrench`` (their header stamps are checked).
It aborts (``/shaping/abort``, std_msgs/String, reliable + transient local,
the reason in ``data``) when

* a tension reaches ``abort_ratio x material.F_break`` (``abort_ratio`` 0, the
  default: the largest ratio safety principle 4 allows at the cell's
  configured speed, from tension rates the core computes at start);
* the trend of the largest tension (least squares over ``trend_window``)
  predicts that threshold within ``detect_time + stop_time`` (the tool's
  reaction and jerk-limited stopping time);
* a tension is NaN or infinite (safety principle 2);
* a header stamp is zero or lies in the future (safety principle 2; on simulated time
  only if it is still ahead of the node's clock ``max_data_age`` later);
* the tension data go stale: no sample for ``max_data_age`` on the steady
  clock (a watchdog timer that does not depend on /clock, safety principle 1), a QoS
  deadline missed, or stamps older than ``max_stamp_age`` on the node clock;
  no data within ``startup_timeout`` of the start is a fault too.

The abort latches (safety principle 3) until ``~/reset`` (std_srvs/Trigger), which also
clears the transient-local abort (the publisher is re-created).  The monitor
publishes a heartbeat ``/shaping/ready`` (std_msgs/Bool) every ``period``:
true while it has fresh, valid data and has not aborted; the planner moves only
then (the interlock, safety principle 6).  ``/shaping/checked`` (std_msgs/UInt64)
acknowledges each judged ``/sheet/tensions`` sample by its DDS sequence number (and
again every ``period``): on simulated time the simulator runs at most its
``monitor_lead`` samples ahead, so a stalled link stalls the simulation, not the
monitor's view of it.  After an abort the acknowledgements wait (at most
``abort_hold``) until ``/shaping/planner_state`` shows the planner off its plan
(:mod:`rheo_shaping.safety.acknowledge`), so simulated time does not run on while
the abort travels.  ``/diagnostics``: OK / WARN / ERROR (STALE
while waiting for data) with tension, safety factor and data age.
"""
from __future__ import annotations

import sys

from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.subscription import Subscription
from std_msgs.msg import Bool, Float64, Float64MultiArray, String, UInt64
from std_srvs.srv import Trigger

from ..params.node_params import MonitorNodeParams
from ..params.cell import CellParams
from ..safety.abort_budget import abort_horizon, monitor_abort_ratio
from ..safety.acknowledge import Acknowledgements
from ..safety.clock_guard import ClockGuard
from ..safety.monitor import TensionMonitor, stale_on_cell_clock
from ..safety.one_of_each import cell_refusal
from ..safety.watchdog import StallGuard
from . import messages as m
from . import topics as T
from .rclpy_private import clock_subscription
from .guards import (CellCheck, OwnedStream, Presence, guard_clock, second_clock,
                     sim_time_active, with_message_info)
from .ros_params import SchemaParameters
from .spin import Yielded, build_or_destroy, run_node
from ..units import NS

TENSION_TOPICS = (T.TENSIONS.contract, T.CONTACT_TENSION.contract)
STAMPED_TOPICS = (T.PROFILE.contract, T.TOOL_WRENCH.contract)


class MonitorNode(Node):
    """Watches the sheet's tensions; aborts, latches, reports."""

    def __init__(self, **node_kwargs):
        super().__init__('monitor', **node_kwargs)
        build_or_destroy(self, self._build, node_kwargs)

    def _build(self, node_kwargs: dict) -> None:
        self.get_logger().info('starting')
        self.params = SchemaParameters(self, {"cell": CellParams, "settings": MonitorNodeParams},
                                       on_change=self._on_parameters,
                                       cli_args=node_kwargs.get('cli_args'))
        self._set_ratio()
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        s = self.settings
        self.pub_abort = self._publisher(T.ABORT)
        self.pub_ready = self._publisher(T.READY)
        self.pub_checked = self._publisher(T.CHECKED)
        self.acks = Acknowledgements(s.abort_hold)   # what /shaping/checked says
        self.pub_diag = self._publisher(T.DIAGNOSTICS)
        self._subs: list[Subscription] = []
        # the tensions only from the simulator of this namespace, the planner's state only
        # from its planner (docs/ros.md, "Who may write what")
        self._owned = {t.contract: OwnedStream(self, t.name, "simulator")
                       for t in (T.TENSIONS, T.CONTACT_TENSION)}
        # the state's stamp dates the tension samples only from the simulator (its other
        # checks, zero, old and future stamps, hold for every writer)
        self._profile_src = OwnedStream(self, T.PROFILE.name, "simulator")
        self._planner_src = OwnedStream(self, T.PLANNER_STATE.name, "planner")
        self._subscribe(s.max_data_age)
        self.create_subscription(T.PLANNER_STATE.type, T.PLANNER_STATE.name,
                                 self._on_planner_state, T.PLANNER_STATE.qos)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.core = TensionMonitor(s, self.cell.material.F_break, self.ratio, self.horizon,
                                   self._steady.now().nanoseconds, TENSION_TOPICS,
                                   STAMPED_TOPICS, on_abort=self._on_abort,
                                   n_links=self.cell.sheet.n_masses + 1)
        # what this node takes from others only after its own checks (docs/safety.md)
        self.clock_guard = ClockGuard(s.max_clock_jump)
        guard_clock(self, self.clock_guard, lambda why: self._abort(f"monitor: {why}"))
        self.cell_check = CellCheck(self, "the monitor", lambda: self.cell)
        self._watchdog_guard = StallGuard(0.5 * s.max_data_age)
        self._watchdog = self.create_timer(s.period, self._on_watchdog, clock=self._steady)
        self._diag_timer = self.create_timer(s.diagnostics_period, self._publish_diagnostics,
                                             clock=self._steady)
        self.get_logger().info(
            f"monitor up: abort at {self.threshold:.4f} N = {self.ratio:.3f} x F_break "
            f"{self.cell.material.F_break:g} N; trend horizon {self.horizon:.3f} s; "
            f"data older than {s.max_data_age:g} s is a fault")
        self.presence = Presence(self, self._yield)     # last: a node that is fully up

    # -- parameters -------------------------------------------------------------------
    @property
    def cell(self) -> CellParams:
        return self.params["cell"]

    @property
    def settings(self) -> MonitorNodeParams:
        return self.params["settings"]

    @property
    def threshold(self) -> float:
        """F_abort [N]."""
        return self.core.threshold

    @property
    def horizon(self) -> float:
        """detect_time + stop_time [s]: how far ahead the trend must stay below the threshold."""
        return abort_horizon(self.cell, self.settings.detect_time, self.settings.stop_time)

    def _set_ratio(self) -> None:
        """``abort_ratio``, or with 0 the principle-4 bound at the configured speed (core runs:
        :func:`~rheo_shaping.safety.abort_budget.monitor_abort_ratio`)."""
        s = self.settings
        choice = monitor_abort_ratio(self.cell, s.abort_ratio, self.horizon, s.noise_sigma)
        self.ratio, self.budget = choice.ratio, choice.budget
        if choice.note:
            self.get_logger().info(choice.note)

    def _on_parameters(self, names: set[str]) -> None:
        """Only the tunable settings change at runtime (the rest is read-only)."""
        if "diagnostics_period" in names:
            self._diag_timer.cancel()
            self.destroy_timer(self._diag_timer)
            self._diag_timer = self.create_timer(self.settings.diagnostics_period,
                                                 self._publish_diagnostics, clock=self._steady)
        self._configure()

    def _publisher(self, topic: T.Topic):
        return self.create_publisher(topic.type, topic.name, topic.qos)

    def _subscribe(self, max_age: float) -> None:
        qos = T.tension_qos(max_age)
        self._subs = [
            self.create_subscription(
                T.TENSIONS.type, T.TENSIONS.name,
                (with_message_info(lambda msg, info: self._on_tensions(msg, info))
                 if self.settings.acknowledge else self._on_tensions), qos,
                event_callbacks=SubscriptionEventCallbacks(
                    deadline=lambda e: self._on_deadline(T.TENSIONS.contract, e))),
            self.create_subscription(
                T.CONTACT_TENSION.type, T.CONTACT_TENSION.name, self._on_contact, qos,
                event_callbacks=SubscriptionEventCallbacks(
                    deadline=lambda e: self._on_deadline(T.CONTACT_TENSION.contract, e))),
            self.create_subscription(
                T.PROFILE.type, T.PROFILE.name,
                lambda msg: self._on_stamped(T.PROFILE.contract, msg), T.PROFILE.qos),
            self.create_subscription(
                T.TOOL_WRENCH.type, T.TOOL_WRENCH.name,
                lambda msg: self._on_stamped(T.TOOL_WRENCH.contract, msg), T.TOOL_WRENCH.qos),
        ]

    # -- state (the core's TensionMonitor decides) -------------------------------------
    def _configure(self) -> None:
        self.core.configure(self.settings, self.cell.material.F_break, self.ratio, self.horizon,
                            self.cell.sheet.n_masses + 1)
        self.acks.hold_ns = int(round(self.settings.abort_hold * NS))

    def _clear(self) -> None:
        self.core.reset(self._steady.now().nanoseconds)

    @property
    def state(self) -> str:
        """waiting -> ready -> aborted (latched until ~/reset)."""
        return self.core.state

    @property
    def abort_reason(self) -> str:
        return self.core.abort_reason

    @property
    def ready(self) -> bool:
        return self.core.ready

    def _abort(self, reason: str) -> None:
        self.core.abort(reason)

    def _on_abort(self, reason: str) -> None:
        self.acks.on_abort(self._steady.now().nanoseconds)     # before the sample's ack
        self.pub_abort.publish(String(data=reason))
        self.pub_ready.publish(Bool(data=False))
        self.get_logger().error(f"ABORT: {reason}")
        self._publish_diagnostics()

    def _on_reset(self, request, response):
        self.destroy_publisher(self.pub_abort)      # drops the transient-local abort sample
        self.pub_abort = self._publisher(T.ABORT)
        was = self.abort_reason
        self._clear()
        self._acknowledge(self.acks.reset())
        response.success = True
        response.message = "re-armed" + (f" (was aborted: {was})" if was else "")
        self.get_logger().info(f"reset: {response.message}")
        return response

    # -- data -------------------------------------------------------------------------
    def _owner_refuses(self, topic: str, info=None) -> bool:
        """Whether a sample of ``topic`` is not the simulator's (a second writer aborts, with
        its node name; a writer the graph does not name yet only drops the sample)."""
        trust = self._owned[topic].take(info)
        if trust.foreign:
            self._abort(f"monitor: {trust.reason}")
        return not trust.trusted

    def _on_tensions(self, msg: Float64MultiArray, info=None) -> None:
        if self._owner_refuses(T.TENSIONS.contract, info):
            return
        self.core.on_tensions(msg.data, self._steady.now().nanoseconds,
                              self.get_clock().now().nanoseconds)
        # judged: the simulator may run on (monitor_lead), unless an abort is on its way
        seq = (info or {}).get("publication_sequence_number", 0)
        self._acknowledge(self.acks.on_judged(seq))

    def _on_planner_state(self, msg: String) -> None:
        if not self._planner_src.trust().trusted:
            return          # another writer's state cannot lift the hold of an abort
        self._acknowledge(self.acks.on_planner_state(msg.data))

    def _acknowledge(self, seq: int | None) -> None:
        if seq and self.settings.acknowledge:
            self.pub_checked.publish(UInt64(data=seq))

    def _on_contact(self, msg: Float64) -> None:
        if self._owner_refuses(T.CONTACT_TENSION.contract):
            return
        self.core.on_contact(msg.data, self._steady.now().nanoseconds,
                             self.get_clock().now().nanoseconds)

    def _on_stamped(self, topic: str, msg) -> None:
        steady = self._steady.now().nanoseconds
        owned = topic == T.PROFILE.contract and self._profile_src.trust().trusted
        self.core.on_stamped(topic, m.stamp_ns(msg.header.stamp), steady,
                             self.get_clock().now().nanoseconds,
                             sim_time_active(self), owned)

    def _on_deadline(self, topic: str, event) -> None:
        self.core.on_deadline(topic)

    # -- watchdog (steady clock) ------------------------------------------------------
    def _yield(self, reason: str) -> None:
        raise Yielded(reason)

    def _not_yet(self) -> str:
        """Why this monitor may not report ready (core: cell_refusal); aborts on a cell that
        is not its own or a second clock."""
        why, fault = cell_refusal("monitor", self.presence.settled, self.settings.check_cell,
                                  self.cell_check.mismatch, lambda: second_clock(self),
                                  T.CELL.contract)
        if fault:
            self._abort(f"monitor: {why}")
        return why

    def _on_watchdog(self) -> None:
        now = self._steady.now().nanoseconds
        self.core.blocked = self._not_yet()
        self.core.cell_clock = stale_on_cell_clock(
            self.settings, sim_time_active(self))
        # this process stood still for over max_data_age / 2 (a busy machine): samples may
        # wait unread behind this timer, so they are judged at the next tick, not now
        stalled = self._watchdog_guard.check(now)
        was = self.state
        ready = self.core.tick(now, self.get_clock().now().nanoseconds, stalled,
                               previous=self._watchdog_guard.previous)
        if ready and was == "waiting":
            self.get_logger().info("ready: fresh tension data")
        elif self.state == "waiting":
            lacks = self.core.waiting_for(now, self.get_clock().now().nanoseconds)
            clock = clock_subscription(self)
            hint = (f"; the simulator's clock: {clock.topic_name} (a cell whose clock is in "
                    f"its namespace: {' '.join(T.CLOCK_REMAP)} on every node)"
                    if clock is not None and "clock" in lacks else "")
            self.get_logger().info(
                f"waiting (not ready, the planner will not move): {lacks}{hint}; tension topics "
                f"{self.resolve_topic_name(T.TENSIONS.name)}, "
                f"{self.resolve_topic_name(T.CONTACT_TENSION.name)}",
                throttle_duration_sec=5.0)
        self.pub_ready.publish(Bool(data=ready))
        self._acknowledge(self.acks.tick(self._steady.now().nanoseconds))   # a lost one too

    def _publish_diagnostics(self) -> None:
        level, message, values = self.core.diagnostics(self._steady.now().nanoseconds)
        name = m.status_name(self.get_namespace(), "monitor")
        self.pub_diag.publish(m.diagnostics_msg(self.get_clock().now().nanoseconds,
                                                name, level, message, values,
                                                m.hardware_id(self.get_namespace())))


def main(args=None):
    return run_node(MonitorNode, 'monitor', args)


if __name__ == '__main__':
    sys.exit(main())
