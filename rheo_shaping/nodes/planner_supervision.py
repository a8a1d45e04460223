"""The ``planner`` node's supervision on the steady clock: when the plan may start, the
monitor's heartbeat, what the planner waits for and says, the start of a run (a part of
:class:`~.planner.PlannerNode`; the decisions are the core's:
:mod:`rheo_shaping.planning.run_state`,
:func:`rheo_shaping.safety.one_of_each.commander_refusal`).
"""
from __future__ import annotations

from rclpy.publisher import Publisher
from std_msgs.msg import String

from ..params.schema import ParameterError
from ..planning.run_state import (SetpointGrid, StartFacts, reported_state, running_decision,
                                  start_decision, start_inputs, start_lead)
from ..planning.stopping import TrajectoryStreamer
from ..safety.one_of_each import commander_refusal
from ..safety.watchdog import StallGuard
from ..units import NS
from . import messages as m
from . import topics as T
from .hosts import PlannerMixin
from .rclpy_private import clock_subscription


class PlannerSupervision(PlannerMixin):
    """The planner node's supervision (mixed into :class:`~.planner.PlannerNode`, whose state
    it reads and sets)."""

    # the node's state this sets (PlannerNode._build initializes it)
    pub_command: Publisher | None       # /tool/command, made once no older twin is known
    streamer: TrajectoryStreamer | None
    grid: SetpointGrid | None
    _supervise_guard: StallGuard | None
    _commander: str | None
    _refused: str

    # -- supervision (steady clock) -------------------------------------------------
    def _on_commander(self, msg: String) -> None:
        self._commander = msg.data

    def _supervise(self) -> None:
        if self.pub_command is None:
            if not self.presence.settled or self.presence.twin:
                return
            why = commander_refusal(self._commander, self.settings.check_cell)
            if why:
                self.get_logger().info(f"waiting: {why}", throttle_duration_sec=5.0)
                return
            self.pub_command = self.create_publisher(T.TOOL_COMMAND.type, T.TOOL_COMMAND.name,
                                                     T.TOOL_COMMAND.qos)
            self._set_state("idle" if not self.settings.autostart else "waiting")
        ok, why = self._monitor_ok()
        # this process stood still for over monitor_timeout / 2 (a busy machine): heartbeats
        # may wait unread behind this timer, so a lost monitor is judged at the next tick
        guard = self._supervise_guard
        if guard is None or guard.limit != 0.5 * self.settings.monitor_timeout:
            guard = self._supervise_guard = StallGuard(0.5 * self.settings.monitor_timeout)
        stalled = guard.check(self._steady.now().nanoseconds)
        if self.streamer is None:
            now = self._now_ns()
            command = self.pub_command
            state, why_not = start_decision(start_inputs(
                StartFacts(aborted=self.latch.aborted, autostart=self.settings.autostart,
                           start_requested=self.latch.start_requested,
                           pose_known=self._tool_pose is not None,
                           hold_known=self.latch.hold is not None, hold_ns=self.latch.hold_ns,
                           pose_ns=self._pose_ns, now_ns=now, monitor_ok=ok),
                lambda: self.count_publishers(T.TOOL_POSE.name), self._tool_away,
                self._refusal, self._start_lead, command.get_subscription_count))
            if state == "start":
                self._start(now)
            elif state in ("idle", "holding"):
                self._update_state()
                return
            elif why_not and state != "waiting_for_pose":
                self._refuse(why_not, state)
            else:
                self._set_state(state)
                self._say_wait(state, why)
        elif self.streamer.state == "running":
            stop = running_decision(
                ok, guard.excuses(stalled, self._ready_rx, self.settings.monitor_timeout), why,
                self._refusal())
            if stop:
                self._abort(stop)
            elif self._adaptive_waits():
                self._stream()          # the paced stream's re-plan, taken on the wall clock
        self._update_state()

    def _say_wait(self, state: str, monitor_why: str) -> None:
        """What a wait waits for: the full topic name and the likely fix, every 5 s."""
        clock = clock_subscription(self)
        command = self.pub_command          # made before any wait for a subscriber
        what = {
            "waiting_for_monitor": (
                f"the monitor's ready heartbeat on {self._ready_topic} ({monitor_why}): the "
                f"monitor is the interlock, no motion without it; start it in this namespace "
                f"(ros2 run rheo_shaping monitor, use_sim_time as here)"),
            "waiting_for_clock": (
                f"/clock on {clock.topic_name if clock else '/clock'}: the simulator publishes "
                f"it on /clock, or with {' '.join(T.CLOCK_REMAP)} in its namespace (then every "
                f"node of the cell needs that remap)"),
            "waiting_for_subscriber": (
                f"a subscriber of {command.topic_name if command else T.TOOL_COMMAND.name} "
                f"(the simulator or the robot)"),
            "waiting_for_pose": (f"the tool pose on {self.resolve_topic_name(T.TOOL_POSE.name)}"
                                 + ("" if self.latch.hold_ns is None else
                                    f" stamped at or after the last run's newest set-point "
                                    f"({self.latch.hold_ns / NS:.3f} s)")),
        }.get(state)
        if what:
            self.get_logger().info(f"waiting for {what}", throttle_duration_sec=5.0)

    def _refuse(self, reason: str, state: str) -> None:
        """Do not start: the state says why, the log once per reason."""
        if reason != self._refused:
            self._refused = reason
            text = f"not starting ({state}): {reason}"
            if state == "waiting":          # one severity per call site (rclpy's logger)
                self.get_logger().info(text)
            else:
                self.get_logger().warning(text)
        self._set_state(state)

    def _start_lead(self, now: int) -> str:
        """Why the stream could not keep within max_lead of the executed pose (core)."""
        return start_lead(now, self._pose_ns, self.settings.max_lead)

    def _start(self, now_ns: int) -> None:
        if self.latch.start_failed:
            self._set_state("error")
            return
        try:
            plan = self._adaptive_plan(self._plan_from(self.latch.start_from(self._tool_pose)))
        except (ParameterError, ValueError, RuntimeError) as exc:
            self.latch.start_failed = str(exc)              # until ~/reset
            self.get_logger().error(f"cannot start: {exc}")
            self._set_state("error")
            return
        streamer = TrajectoryStreamer(home_xz=self.cell_used.tool.home,
                                      retract_limits=self._retract_limits())
        streamer.start(plan, now_ns / NS)
        self.streamer = streamer
        self.grid = SetpointGrid(now_ns, int(round(NS / self.settings.control_rate)))
        self.pub_trajectory.publish(m.trajectory_msg(
            plan, now_ns, self.settings.trajectory_period))
        self.get_logger().info(f"starting the plan at t = {now_ns / NS:.3f} s "
                               f"({plan.duration:.1f} s, {len(plan.segments)} segments)")
        self._stream()

    def _update_state(self) -> None:
        st = self.streamer
        state = reported_state(None if st is None else st.state, self.latch.aborted,
                               self._now_ns(), self._t0_ns, self.cell_used.movement.process_time)
        if state is not None:
            self._set_state(state)
