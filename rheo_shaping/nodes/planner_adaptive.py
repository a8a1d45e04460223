"""The ``planner`` node's closed loop (``adaptive: true``): samples of the run in, the
core's re-plan out (a part of :class:`~.planner.PlannerNode`; the decisions are the
core's: :class:`rheo_shaping.adaptive.streamed.StreamedLoop` over
:class:`rheo_shaping.adaptive.online.OnlineShaper`).

The node keeps the newest ``/tool/wrench`` and ``/sheet/contact_tension`` and, at each
executed tool pose the shaper wants, one :class:`~rheo_shaping.adaptive.observe.Sample`;
when a refresh is due it runs in the closed loop's worker process
(:class:`rheo_shaping.adaptive.worker.ShaperProcess`: the estimate and the re-plan take
tenths of a second of CPU that would hold this interpreter), joined
``adaptive_join_lead`` after the newest set-point sent, and
the next control tick switches the stream to it
(:meth:`~rheo_shaping.planning.stopping.TrajectoryStreamer.replace_rest`) or drops it when
the stream has already passed the join or stopped.  Each refresh is published on
``/shaping/estimate`` and logged with its reason; each re-plan on
``/tool/planned_trajectory``.  The monitor knows none of it.
"""
from __future__ import annotations

import json

from geometry_msgs.msg import WrenchStamped
from std_msgs.msg import Float64, String

from ..adaptive.online import OnlineConfig
from ..adaptive.streamed import StreamedLoop
from ..adaptive.worker import ShaperProcess
from ..jsonable import json_safe
from . import messages as m
from . import topics as T
from .hosts import PlannerMixin
from .guards import sim_time_active


class PlannerAdaptive(PlannerMixin):
    """The planner node's closed loop (mixed into :class:`~.planner.PlannerNode`)."""

    def _setup_adaptive(self) -> None:
        self.loop: StreamedLoop | None = None   # the running run's closed loop (core)
        self._wrench: tuple[float, float] | None = None
        self._contact: float | None = None
        self.adaptive_log: list[dict] = []      # every refresh of this node (as published)
        self._shaper_process: ShaperProcess | None = None
        if not self.settings.adaptive:
            return
        self._shaper_process = ShaperProcess(self.cell_used, self._online_config())
        self.pub_estimate = self.create_publisher(T.ESTIMATE.type, T.ESTIMATE.name,
                                                  T.ESTIMATE.qos)
        self.pub_loop_diag = self.create_publisher(T.DIAGNOSTICS.type, T.DIAGNOSTICS.name,
                                                   T.DIAGNOSTICS.qos)
        self.create_subscription(T.TOOL_WRENCH.type, T.TOOL_WRENCH.name, self._on_wrench,
                                 T.TOOL_WRENCH.qos)
        self.create_subscription(T.CONTACT_TENSION.type, T.CONTACT_TENSION.name,
                                 self._on_contact, T.CONTACT_TENSION.qos)

    def _online_config(self) -> OnlineConfig:
        s = self.settings
        return OnlineConfig(refresh_period=s.adaptive_refresh, join_lead=s.adaptive_join_lead)

    def _adaptive_refusal(self) -> str:
        """Why a run may not start yet: the closed loop's worker is still starting."""
        proc = self._shaper_process
        if proc is not None and not proc.warm:
            return "the closed loop's worker process is starting (adaptive)"
        return ""

    def _close_adaptive(self) -> None:
        """End the closed loop's worker process (the node is destroyed)."""
        if self._shaper_process is not None:
            self._shaper_process.close()
            self._shaper_process = None

    def _on_wrench(self, msg: WrenchStamped) -> None:
        self._wrench = (float(msg.wrench.force.x), float(msg.wrench.force.z))

    def _on_contact(self, msg: Float64) -> None:
        self._contact = float(msg.data)

    def _adaptive_plan(self, plan):
        """The plan a run starts: the shaper's (the params file's movement as a schedule)
        when ``adaptive`` and the run starts at the movement's start; else ``plan``."""
        self.loop = None
        if self._shaper_process is None:
            return plan
        if plan is not self.plan:
            self.get_logger().warning("adaptive: this run starts with an approach from where "
                                      "the tool is: it follows the fixed plan")
            return plan
        s = self.settings
        online = self._shaper_process.start(self.cell_used, self._online_config())
        paced = s.adaptive_pace and sim_time_active(self)
        if s.adaptive_pace and not paced:
            self.get_logger().warning("adaptive_pace is ignored on wall time: a real tool "
                                      "cannot wait for a refresh")
        self.loop = StreamedLoop(online, self._shaper_process, paced=paced)
        self.get_logger().info(f"adaptive: estimating the material every "
                               f"{s.adaptive_refresh:g} s of process time; the pessimistic "
                               f"F_max kept under {online.limits.F_limit:.3f} N")
        return online.plan

    def _adaptive_limit(self, limit_ns: int) -> int:
        """The newest set-point time [ns] to send: ``limit_ns``, or a paced loop's join."""
        st = self.streamer
        cap = None if self.loop is None or st is None else self.loop.limit_ns(st.state)
        return limit_ns if cap is None else min(limit_ns, cap)

    def _adaptive_waits(self) -> bool:
        """A paced stream waits at its join and is to be served now: its refresh finished,
        or the wait ran out (core: StreamedLoop.serve_now)."""
        return self.loop is not None and self.loop.serve_now()

    def _adaptive_pose(self, xz, stamp_ns: int) -> None:
        """A sample of the run at the executed pose's time, when the shaper wants one."""
        if self.loop is not None:
            self.loop.pose(xz, stamp_ns, self._t0_ns, self._wrench, self._contact)

    def _adaptive_tick(self) -> None:
        """Switch to a finished re-plan, then begin the next refresh when one is due."""
        loop, st, grid = self.loop, self.streamer, self.grid
        if loop is None or st is None or grid is None:
            return
        try:
            taken = loop.tick(st, grid, self._pose_ns, self._tool_pose)
        except Exception as exc:            # the worker's error, named; never lost
            why = f"the refresh failed ({exc!r}): the running plan goes on, no further re-plan"
            self.get_logger().error(f"adaptive: {why}")
            self._loop_status("ERROR", why, {})
            self.loop = None
            return
        if taken is None:
            return
        step = taken.step
        if taken.switched:
            self.pub_trajectory.publish(m.trajectory_msg(
                step.plan, grid.t0_ns, self.settings.trajectory_period))
        self.adaptive_log.append(taken.data)
        self.pub_estimate.publish(String(data=json.dumps(json_safe(taken.data))))
        self._loop_status(*taken.status())
        text = (f"adaptive ({step.reason.value} at t = {step.t:.2f} s, "
                f"{step.estimate.cost_s + (step.replan.cost_s if step.replan else 0):.2f} s "
                f"CPU): {taken.note}{step.message}")
        if taken.warning:                   # one severity per call site (rclpy's logger)
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)

    def _loop_status(self, level: str, message: str, values: dict) -> None:
        """The closed loop's status on /diagnostics (``<ns>/planner: closed loop``)."""
        self.pub_loop_diag.publish(m.diagnostics_msg(
            self._now_ns(), m.status_name(self.get_namespace(), "planner"), level, message,
            values, m.hardware_id(self.get_namespace())))
