"""What the ``simulator`` node publishes: the sheet's state, the simulated camera, markers,
/diagnostics and progress lines (a part of :class:`~.simulator.SimulatorNode`; the
decisions are the core's: :class:`rheo_shaping.sheet.cadence.Cadence`,
:func:`rheo_shaping.sheet.setpoints.run_status`)."""
from __future__ import annotations

import math

import numpy as np

from ..records.measurement import MeasurementParams, profile_frame
from ..sheet.cadence import Cadence, RateMeter
from ..sheet.setpoints import run_status
from . import messages as m
from .hosts import SimulatorMixin


class SimulatorOutputs(SimulatorMixin):
    """The simulator node's publishing (mixed into :class:`~.simulator.SimulatorNode`, whose
    state it reads); what is due when: the core's
    :class:`~rheo_shaping.sheet.cadence.Cadence`."""

    # the node's state this reads (SimulatorNode._build and _new_run initialize it)
    cadence: Cadence
    rate: RateMeter

    @property
    def achieved_factor(self) -> float:
        """The achieved real-time factor at the newest /diagnostics."""
        return self.rate.factor

    # -- publishing -------------------------------------------------------------------
    def _publish(self, t_ns: int) -> None:
        if self.cadence.state_due(t_ns):
            self._publish_state(t_ns)
        if self.cadence.camera_due(t_ns):
            self._publish_camera(t_ns)
        self._publish_steady(t_ns)

    def _publish_steady(self, t_ns: int) -> None:
        """What goes out on the steady clock: markers, /diagnostics, progress lines."""
        now = self._steady.now().nanoseconds
        if self.cadence.markers_due(now):
            self.pub_markers.publish(m.markers_msg(
                t_ns, self.sim.nodes(), self.run.tensions(), self._run_cell.material.F_break,
                self._run_cell.sheet.thickness, self._tool_outline + self.sim.state.tool,
                self._cake_outline))
        if self.cadence.diagnostics_due(now):
            self._measure_rate(now)
            self.pub_diag.publish(self._diagnostics(t_ns))
        if self.cadence.progress_due(self.sim.state.t, self.started):
            self._progress()

    def _publish_state(self, t_ns: int) -> None:
        self.cadence.state_sent(t_ns)
        st = self.sim.state
        self.pub_profile.publish(m.profile_msg(st.x, t_ns))
        self._publish_tensions()
        self.pub_pose.publish(m.pose_msg(st.tool, t_ns))
        self.pub_wrench.publish(m.wrench_msg(self.sim.tool_force(), t_ns))

    def _publish_tensions(self) -> None:
        contact = math.nan if self.run.broken else self.sim.contact_tension()
        self.pub_tensions.publish(m.tensions_msg(self.run.tensions()))
        self._lead.published()
        self.pub_contact.publish(m.float_msg(contact))

    def _hold_camera(self) -> None:
        """While /clock holds: camera frames of the waiting sheet at the rate they come at when
        running, for late joiners."""
        if self.cadence.hold_camera_due(self._steady.now().nanoseconds):
            self._publish_camera(self.timeline.t_ns)

    def _publish_camera(self, t_ns: int) -> None:
        """A frame of the simulated camera (rheo_shaping.records.measurement.profile_frame)."""
        s = self.settings
        if self.run.broken or self._camera_rng.random() < s.camera_frame_dropout:
            return
        ms = MeasurementParams(profile_spacing=s.camera_spacing, profile_noise=s.camera_noise,
                               point_dropout=s.camera_point_dropout)
        pts = profile_frame(self.sim.nodes(), ms, self._camera_rng)
        self.pub_camera.publish(m.profile_msg(pts, t_ns))

    def _measure_rate(self, now: int) -> None:
        self.rate.measure(now, self.timeline.t_ns)
        if self._sim_clock and self.started and self.summary is None and self.rate.lagging():
            self.get_logger().warning(
                f"running at {self.rate.factor:.1f}x instead of {self.rate.wanted:g}x "
                f"(computation or set-points lag; lockstep waits so far: {self.timeline.waits})",
                throttle_duration_sec=10.0)

    def _progress(self) -> None:
        st = self.sim.state
        self.get_logger().info(
            f"t = {st.t:6.1f} s: tool ({st.tool[0] * 1e3:.2f}, {st.tool[1] * 1e3:.2f}) mm, "
            f"largest tension {float(np.max(st.tension)):.4f} N, contact "
            f"{self.sim.contact_tension():.4f} N, F_max so far {self.peak.value:.4f} N, "
            f"x{self.rate.factor:.1f} real time")

    def _diagnostics(self, t_ns: int):
        st = self.sim.state
        level, message = run_status(self.run.broken, self.gate.held, self.started,
                                    self.summary is not None, float(st.t),
                                    self._run_cell.movement.process_time)
        values = {"process_time": float(st.t), "tool_x": float(st.tool[0]),
                  "tool_z": float(st.tool[1]),
                  "tension_max": float(np.max(self.run.tensions())),
                  "F_max": float(self.peak.value) if self.started else 0.0,
                  "real_time_factor": self.settings.real_time_factor,
                  "achieved_factor": float(self.rate.factor),
                  "lockstep_waits": self.timeline.waits,
                  "monitor_waits": self._lead.waits, "clock_holds": self.timeline.clock_holds,
                  "late_steps": self.timeline.late_steps}
        if self.summary is not None:
            values.update({"final_F_max": self.summary.F_max, "final_SF": self.summary.SF,
                           "final_delta": self.summary.delta})
        name = m.status_name(self.get_namespace(), "simulator")
        return m.diagnostics_msg(t_ns, name, level, message, values,
                                 m.hardware_id(self.get_namespace()))
