"""The ``planner`` node: jerk-limited tool plans, streamed as set-points, with a planned stop.

The plan is the core's: ``movement.movement_plan(params)``
(the paper's movements 1-4, or movement 0 = the params file's waypoints and
dwells), a chain of ruckig state-to-state segments, at rest at every waypoint,
straight lines by phase synchronisation, dwells between.  It is the same plan
the offline run (``rheo-shaping simulate``) uses.  With ``optimise_d`` the node
first picks movement 4's d with the core model (:func:`rheo_shaping.planning.choose_d.best_d`).

Interlock (safety principle 6, docs/safety-principles.md).  With ``wait_for_monitor`` the planner
starts only while the monitor's ``/shaping/ready`` heartbeat says ready and is
younger than ``monitor_timeout`` (steady clock); a heartbeat that stops or
turns false while the tool moves is treated as an abort.

Streaming.  The plan starts only once ``/tool/command`` has a matched subscriber
(state ``waiting_for_subscriber`` until then): set-points sent to nobody would make a
simulator or robot that matches later join mid-plan.  From the start time t0 (the
node clock: simulated time with ``use_sim_time``) a
:class:`~rheo_shaping.planning.stopping.TrajectoryStreamer` gives the set-point at
t0 + k / ``control_rate``; they are published on ``/tool/command``, each stamped
with its time (on simulated time, when /clock jumps by more than one period, every
set-point in between is published, plus one at the clock's time).  The whole plan
is published once on ``/tool/planned_trajectory`` (transient local; header stamp = t0).

Abort (safety principles 3 and 5).  ``/shaping/abort`` (transient local) makes the
streamer stop at once from the exact current state with ruckig (target: rest,
within the plan's acceleration and jerk limits), then retract slowly to
``tool.home`` (``retract_*`` limits) and hold.  The abort latches: the old
plan is never resumed; ``~/reset`` (std_srvs/Trigger, refused while the tool
moves) re-arms the planner, which then runs the plan again from where the
tool holds (an approach move at the retract limits first) when the interlock
allows.  At the end of the process (``movement.process_time`` and the plan
over) it holds and reports ``done`` on ``/shaping/planner_state``.
"""
from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger

from ..planning.clearance import require_clearance
from ..params.node_params import PlannerNodeParams
from ..planning.choose_d import best_d, d_values
from ..params.cell import CellParams
from ..planning.plans import MotionLimits, Plan
from ..planning.movement import approach_plan, autostart_refusal, movement_plan
from ..params.schema import ParameterError
from ..planning.run_state import (Heartbeat, RunLatch, SetpointGrid, executed_ns, interlock,
                                  lead_limit, lead_wait, reset_refusal, start_reply, stop_run)
from ..planning.stopping import TrajectoryStreamer
from ..safety.clock_guard import ClockGuard
from ..safety.one_of_each import cell_refusal
from ..safety.watchdog import StallGuard
from . import messages as m
from . import topics as T
from .guards import (CellCheck, OwnedStream, Presence, guard_clock, second_clock,
                     sim_time_active)
from .planner_adaptive import PlannerAdaptive
from .planner_supervision import PlannerSupervision
from .ros_params import SchemaParameters
from .spin import Yielded, build_or_destroy, run_node
from ..units import NS


class PlannerNode(PlannerSupervision, PlannerAdaptive, Node):
    """Plans the shaping movement and streams it, behind the monitor's interlock."""

    def __init__(self, **node_kwargs):
        super().__init__('planner', **node_kwargs)
        build_or_destroy(self, self._build, node_kwargs)

    def _build(self, node_kwargs: dict) -> None:
        self.get_logger().info('starting: parameters, then the plan')
        self.params = SchemaParameters(self, {"cell": CellParams, "settings": PlannerNodeParams},
                                       cli_args=node_kwargs.get('cli_args'))
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        # /tool/command is created once no older planner of this name is known (a twin
        # that yields never shows up as a second commander, _supervise)
        self.pub_command = None
        pub = T.PLANNED_TRAJECTORY
        self.pub_trajectory = self.create_publisher(pub.type, pub.name, pub.qos)
        pub = T.PLANNER_STATE
        self.pub_state = self.create_publisher(pub.type, pub.name, pub.qos)
        subs = {topic.contract: self.create_subscription(topic.type, topic.name, callback,
                                                         topic.qos)
                for topic, callback in ((T.ABORT, self._on_abort), (T.READY, self._on_ready),
                                        (T.TOOL_POSE, self._on_pose))}
        self._ready_topic = subs[T.READY.contract].topic_name      # resolved (namespace)
        self._ready_src = OwnedStream(self, T.READY.name, "monitor")   # only the monitor's
        self._tool_pose: np.ndarray | None = None     # the latest measured tool pose [m]
        self._pose_ns: int | None = None              # its stamp: the executed time [ns]
        self._lead_note = ""                          # why set-points wait for execution
        self._refused = ""                            # the last reason not to start (logged)
        # what this node takes from others only after its own checks (docs/safety.md)
        self.clock_guard = ClockGuard(self.settings.max_clock_jump)
        guard_clock(self, self.clock_guard, lambda why: self._abort(f"planner: {why}"))
        self.cell_check = CellCheck(self, "the planner", lambda: self.cell,
                                    on_first=lambda: self.presence.discovered())
        self._commander: str | None = None     # the planner the simulator follows ("" none)
        self.create_subscription(T.COMMANDER.type, T.COMMANDER.name, self._on_commander,
                                 T.COMMANDER.qos)
        self.create_service(Trigger, '~/start', self._on_start)
        self.create_service(Trigger, '~/reset', self._on_reset)

        self.cell_used, self.plan = self._make_plan()
        self._setup_adaptive()
        self.streamer: TrajectoryStreamer | None = None
        self.latch = RunLatch()      # abort, start asked, start failed, the hold (core)
        self.grid: SetpointGrid | None = None       # the run's set-point times (core)
        self._ready = False
        self._ready_rx: int | None = None
        self._supervise_guard: StallGuard | None = None
        self._state = ""
        self._command_timer = self.create_timer(1.0 / self.settings.control_rate, self._stream)
        self.create_timer(0.05, self._supervise, clock=self._steady)
        mv = self.cell_used.movement
        self.get_logger().info(
            f"planner up: movement {mv.number}, plan {self.plan.duration:.1f} s "
            f"(process {mv.process_time:g} s), {len(self.plan.segments)} segments, "
            f"{self.settings.control_rate:g} Hz set-points"
            + (", waiting for the monitor" if self.settings.wait_for_monitor else ""))
        if self.plan.duration > mv.process_time:
            self.get_logger().warning(
                f"the plan lasts {self.plan.duration:.1f} s, longer than movement.process_time = "
                f"{mv.process_time:g} s: the process figures are taken at {mv.process_time:g} s "
                f"and the plan is finished after it")
        self._set_state("starting")       # idle / waiting once it knows it is the only one
        # it acts once it has its /tool/command writer: a twin that has none yet yields
        self.presence = Presence(self, self._yield, acting=lambda: self.pub_command is not None)

    # -- parameters and plan --------------------------------------------------------
    def destroy_node(self) -> None:
        if getattr(self, "_shaper_process", None) is not None:
            self._close_adaptive()                 # the closed loop's worker process
        super().destroy_node()

    @property
    def cell(self) -> CellParams:
        return self.params["cell"]

    @property
    def settings(self) -> PlannerNodeParams:
        return self.params["settings"]

    def _make_plan(self) -> tuple[CellParams, Plan]:
        cell, s = self.cell, self.settings
        if s.optimise_d and cell.movement.number == 4:
            ds = d_values(s.d_min, s.d_max, s.d_step)
            self.get_logger().info(f"optimise_d: running the core for {len(ds)} values of d "
                                   f"in [{s.d_min * 1e3:g}, {s.d_max * 1e3:g}] mm ...")
            try:
                choice = best_d(cell, ds, s.delta_limit, workers=s.optimise_workers)
            except ValueError as exc:
                raise ParameterError(f"optimise_d: {exc}") from None
            self.get_logger().info(
                f"optimise_d: d = {choice.d * 1e3:.2f} mm, predicted F_max = {choice.F_max:.4f} "
                "N, "
                f"Delta = {choice.delta * 1e3:.3f} mm (limit {s.delta_limit * 1e3:g} mm)")
            cell = replace(cell, movement=replace(cell.movement, d=choice.d))
        try:
            plan = movement_plan(cell).plan
        except (ValueError, RuntimeError) as exc:
            raise ParameterError(f"the movement cannot be planned: {exc}") from None
        self._check_clearance(cell, plan)
        return cell, plan

    def _check_clearance(self, cell: CellParams, plan: Plan) -> None:
        """Refuse a plan that leaves less room than the sheet between tool and mould."""
        require_clearance(cell, plan, self.settings.clearance_factor)

    def _plan_from(self, start_xz) -> Plan:
        """The plan, preceded by an approach from ``start_xz`` when the tool is elsewhere."""
        plan = approach_plan(self.cell_used, self.plan, start_xz, self._retract_limits())
        if plan is not self.plan:
            self._check_clearance(self.cell_used, plan)
        return plan

    def _retract_limits(self) -> MotionLimits:
        s = self.settings
        return MotionLimits(s.retract_speed, s.retract_accel, s.retract_jerk)

    # -- state ----------------------------------------------------------------------
    @property
    def state(self) -> str:
        return self._state

    def _set_state(self, state: str) -> None:
        if state != self._state:
            self._state = state
            self.pub_state.publish(String(data=state))
            self.get_logger().info(f"state: {state}")

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _monitor_ok(self) -> tuple[bool, str]:
        return interlock(Heartbeat(
            required=self.settings.wait_for_monitor, received_ns=self._ready_rx,
            now_ns=self._steady.now().nanoseconds, timeout=self.settings.monitor_timeout,
            ready=self._ready), lambda: self._ready_src.trust().reason)

    # -- callbacks ------------------------------------------------------------------
    def _on_ready(self, msg: Bool) -> None:
        self._ready = bool(msg.data)
        self._ready_rx = self._steady.now().nanoseconds

    def _on_pose(self, msg: PoseStamped) -> None:
        self._tool_pose = np.array(m.pose_xz(msg), dtype=float)
        stamp = m.stamp_ns(msg.header.stamp)
        if self._pose_ns is None or stamp > self._pose_ns:
            self._pose_ns = stamp
            self._adaptive_pose(self._tool_pose, stamp)
            if self.streamer is not None and self._lead_note:
                self._stream()                  # execution caught up: the stream goes on

    def _yield(self, reason: str) -> None:
        """An older planner of this name runs: this one never moves the tool."""
        if self.streamer is not None:
            self._abort(f"planner: {reason}")
        raise Yielded(reason)

    def _refusal(self) -> str:
        """Why the plan may not start now (twins, the closed loop's worker, cell, clocks;
        core: cell_refusal); "" if it may.  (A second /shaping/ready publisher: the
        interlock, _monitor_ok.)"""
        settled = self.presence.settled
        starting = self._adaptive_refusal() if settled and self.streamer is None else ""
        return starting or cell_refusal("planner", settled, self.settings.check_cell,
                                        self.cell_check.mismatch, lambda: second_clock(self),
                                        T.CELL.contract)[0]

    def _tool_away(self) -> str:
        """Why autostart is unsafe (:func:`~rheo_shaping.planning.movement.autostart_refusal`)."""
        if self._tool_pose is None or self.latch.hold is not None:
            return ""
        return autostart_refusal(self._tool_pose, self.cell_used.tool.home, self.plan.start,
                                 self.settings.start_tolerance)

    def _on_abort(self, msg: String) -> None:
        self._abort(f"monitor: {msg.data}")

    @property
    def aborted(self) -> bool:
        return self.latch.aborted

    @property
    def abort_reason(self) -> str:
        return self.latch.abort_reason

    def _abort(self, reason: str) -> None:
        if not self.latch.abort(reason):
            return
        stop = self._stop_run(reason)
        if stop is None:
            self.get_logger().error(f"ABORT ({reason}) before the start: the plan will not run "
                                    f"(~/reset to re-arm)")
        else:
            self.get_logger().error(f"ABORT ({reason}): {stop[1]}")
            self._stream()
        self._update_state()

    def _stop_run(self, reason: str) -> tuple[list[int], str] | None:
        """The run stopped from the executed pose (core: stop_run), the set-points it
        rewinds sent again; stop_run's answer."""
        stop = stop_run(self.streamer, self.grid, reason, self._executed_ns(self._now_ns()))
        for t_send in stop[0] if stop is not None else ():
            self._publish_setpoint(t_send)
        return stop

    def _executed_ns(self, now: int) -> int:
        """The time of the executed tool pose during the run [ns] (core: executed_ns)."""
        return executed_ns(now, self._last_cmd_ns, self._pose_ns, self._t0_ns)

    def _on_start(self, request, response):
        response.success, response.message = start_reply(
            None if self.streamer is None else self._state,
            self.abort_reason if self.aborted else None, self.presence.settled)
        if response.success:
            self.latch.request_start(self._tool_away(), self._tool_pose)
        return response

    def _on_reset(self, request, response):
        why = reset_refusal(None if self.streamer is None else self.streamer.state)
        if why:
            response.success, response.message = False, why
            return response
        response.message = self.latch.rearm(self.streamer, self._last_cmd_ns, self._now_ns())
        response.success = True
        self.streamer = None
        self.grid = None
        self._set_state("idle" if not self.settings.autostart else "waiting")
        self.get_logger().info(f"reset: {response.message}")
        return response

    # -- streaming (node clock) -----------------------------------------------------
    @property
    def _t0_ns(self) -> int | None:
        """The run's start on the node clock [ns] (None before it)."""
        return None if self.grid is None else self.grid.t0_ns

    @property
    def _last_cmd_ns(self) -> int | None:
        """The newest set-point time sent [ns]."""
        return None if self.grid is None else self.grid.last_ns

    def _stream(self) -> None:
        if self.streamer is None or self.grid is None:
            return
        now = self._now_ns()
        limit = lead_limit(self.grid.t0_ns, self._pose_ns, self.settings.max_lead)
        note = lead_wait(now, limit, self._pose_ns, self.settings.max_lead)
        if note and not self._lead_note:
            self.get_logger().warning(note, throttle_duration_sec=5.0)
        self._lead_note = note
        self._adaptive_tick()                   # a finished re-plan first, then the set-points
        skipped = self.grid.skipped
        for t in self.grid.due(now, self._adaptive_limit(limit), sim_time_active(self)):
            self._publish_setpoint(t)
        if self.grid.skipped > skipped:
            self.get_logger().warning(f"the clock jumped {self.grid.skipped - skipped} control "
                                      f"periods beyond a batch: skipping ahead",
                                      throttle_duration_sec=5.0)
        self._update_state()

    def _publish_setpoint(self, t_ns: int) -> None:
        st, pub = self.streamer, self.pub_command
        assert st is not None and pub is not None      # only while a run streams
        pos, _, _ = st.setpoint(t_ns / NS)
        pub.publish(m.pose_msg(pos, t_ns))


def main(args=None):
    return run_node(PlannerNode, 'planner', args)


if __name__ == '__main__':
    sys.exit(main())
