"""The ``planner`` node's closed loop (``adaptive: true``): samples of the run in, the
core's re-plan out (a part of :class:`~.planner.PlannerNode`; the decisions are the
core's: :class:`rheo_shaping.adaptive.online.OnlineShaper`).

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
from concurrent.futures import Future

from geometry_msgs.msg import WrenchStamped
from std_msgs.msg import Float64, String

from ..adaptive.observe import Sample
from ..adaptive.online import OnlineConfig, OnlineShaper, OnlineStep
from ..adaptive.worker import ShaperProcess
from ..jsonable import json_safe
from ..planning.stopping import TrajectoryStreamer
from ..units import NS
from . import messages as m
from . import topics as T
from .hosts import PlannerMixin


class PlannerAdaptive(PlannerMixin):
    """The planner node's closed loop (mixed into :class:`~.planner.PlannerNode`)."""

    def _setup_adaptive(self) -> None:
        self.online: OnlineShaper | None = None
        self._wrench: tuple[float, float] | None = None
        self._contact: float | None = None
        self._samples: list[Sample] = []
        self._work: Future | None = None
        self.adaptive_log: list[dict] = []      # every refresh of this node (as published)
        self._span = 0.0                        # s of process time the last refresh took
        self._began = 0.0                       # s, the stream's time when it began
        self._shaper_process: ShaperProcess | None = None
        if not self.settings.adaptive:
            return
        self._shaper_process = ShaperProcess(self.cell_used, self._online_config())
        self.pub_estimate = self.create_publisher(T.ESTIMATE.type, T.ESTIMATE.name,
                                                  T.ESTIMATE.qos)
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
        self.online = None
        if self._shaper_process is None:
            return plan
        if plan is not self.plan:
            self.get_logger().warning("adaptive: this run starts with an approach from where "
                                      "the tool is: it follows the fixed plan")
            return plan
        s = self.settings
        self.online = self._shaper_process.start(self.cell_used, self._online_config())
        self._samples, self._work = [], None
        self.get_logger().info(f"adaptive: estimating the material every "
                               f"{s.adaptive_refresh:g} s of process time; the pessimistic "
                               f"F_max kept under {self.online.limits.F_limit:.3f} N")
        return self.online.plan

    def _adaptive_pose(self, xz, stamp_ns: int) -> None:
        """A sample of the run at the executed pose's time, when the shaper wants one."""
        if self.online is None or self._t0_ns is None or self._wrench is None:
            return
        t = (stamp_ns - self._t0_ns) / NS
        if t >= 0.0 and self.online.wants(t) and (not self._samples
                                                  or t > self._samples[-1].t):
            sample = Sample(t=t, tool=(float(xz[0]), float(xz[1])), wrench=self._wrench,
                            contact_tension=self._contact)
            self.online.add(sample)
            self._samples.append(sample)

    def _adaptive_tick(self) -> None:
        """Switch to a finished re-plan, then begin the next refresh when one is due."""
        online, st, grid, proc = self.online, self.streamer, self.grid, self._shaper_process
        if online is None or st is None or grid is None or proc is None:
            return
        t0 = grid.t0_ns
        if self._work is not None and self._work.done():
            work, self._work = self._work, None
            last = grid.last_ns
            assert last is not None             # a refresh begins after a set-point is sent
            self._span = (last - t0) / NS - self._began
            try:
                index, step, cpu = work.result()
            except Exception as exc:            # the worker's error, named; never lost
                self._failed(exc)
                return
            proc.cpu_s += cpu
            self._take(index, step, proc, st, t0)
        last, pose_ns, pose = grid.last_ns, self._pose_ns, self._tool_pose
        if (self._work is not None or st.state != "running" or pose_ns is None
                or pose is None or last is None or pose_ns < t0):
            return
        t = (pose_ns - t0) / NS
        reason = online.due(t)
        if reason is None:
            return
        samples, self._samples = self._samples, []
        streamed = self._began = (last - t0) / NS
        lead = 2.0 * self._span           # the join after the stream's lead of the last one
        self._work = proc.submit(samples, t, reason, (float(pose[0]), float(pose[1])),
                                 streamed, lead)

    def _failed(self, exc: BaseException) -> None:
        self.get_logger().error(f"adaptive: the refresh failed ({exc!r}): the running plan "
                                f"goes on, no further re-plan")
        self.online = None

    def _take(self, index: int, result: OnlineStep, proc: ShaperProcess,
              st: TrajectoryStreamer, t0_ns: int) -> None:
        """Refresh ``index``'s result (of ``proc``, the running ``st`` since ``t0_ns``)."""
        switched = ""
        if result.plan is not None:
            try:
                st.replace_rest(result.plan, result.t_join)
                proc.accept(index, result)
                self.pub_trajectory.publish(m.trajectory_msg(
                    result.plan, t0_ns, self.settings.trajectory_period))
                switched = f"re-planned from t = {result.t_join:.2f} s: "
            except (RuntimeError, ValueError) as exc:
                switched = f"re-plan dropped ({exc}): "
        data = dict(result.as_dict(), switched=switched.startswith("re-planned"),
                    worker_cpu_s=proc.cpu_s)
        self.adaptive_log.append(data)
        self.pub_estimate.publish(String(data=json.dumps(json_safe(data))))
        log = self.get_logger().info if result.plan is None or switched.startswith("re") \
            else self.get_logger().warning
        log(f"adaptive ({result.reason.value} at t = {result.t:.2f} s, "
            f"{result.estimate.cost_s + (result.replan.cost_s if result.replan else 0):.2f} s "
            f"CPU): {switched}{result.message}")
