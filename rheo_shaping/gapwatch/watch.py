"""The gap watch: the model beside the running cell, sample by sample (issue 29).

:class:`GapWatch` takes a cell's measured streams as they arrive (the robot's
tool pose, the camera's profile frames, the load cell's force on the tool),
drives the sheet model of a model cell with the measured tool pose (averaged
over ``POSE_WINDOW`` = 0.4 s, as the diagnosis does, :mod:`..diagnosis.compare`),
steps it with the compiled kernel as far as the poses reach (only whole solver
steps, so the model takes the steps an offline run takes), and compares:

* each camera point's signed normal distance to the model's centreline at the
  frame's time [m] (the diagnosis's profile residual);
* the measured force on the tool minus the model's, per axis [N].

The noise of each observable is estimated online (robust MAD of second
differences: of a frame's residuals along the sheet, of each force axis in time,
:func:`mad_sigma`), never below ``min_*_noise``.
Residuals are reported as RMS, systematic part sqrt(max(RMS^2 - s^2, 0)) and
RMS / s (noise units: 1 is noise only), over a sliding ``window``, over the
run so far and per phase (``approach``, ``forced deformation``, ``dwell``,
``release``, ``settle``, decided online from the model's tool contact and the
measured tool's motion: a move in contact after a dwell counts as release).

States: ``OK``; ``WARN`` when a residual (window or run, profile or force)
stays above its :class:`~.floor.ResidualFloor` for ``sustain`` seconds of process time;
``ERROR`` when, for as long, the gap is large enough to change the process
figures by more than ``error_share``: the systematic tool-force residual over
the window against the model's peak tool force so far (the tool force is the
measured proxy of F_max), or the measured Delta (median over the window's
frames, corrected by the floor's ``delta_bias_m``) against the model's;
``STALE`` before data; ``FAILED`` when the model's solver fails.

Samples are taken in, timed and refused by :mod:`.intake` (its docstring).
"""
from __future__ import annotations

import bisect
import math
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ..diagnosis.compare import POSE_WINDOW
from ..diagnosis.where import PHASES
from ..params.gapwatch_params import GapWatchNodeParams
from ..params.cell import CellParams
from ..records.record import Record
from ..sheet.metrics import residual_gap
from ..sheet.chain import ConvergenceError
from ..sheet.simulation import TOOL, Simulation
from .floor import ResidualFloor
from .intake import NOISE_SAMPLES, StreamIntake, _Frame
from .residuals import Status, _Sums, mad_sigma, signed_distance

#: A frame's residuals and a force sample are judged once the model has passed their time;
#: model states older than this [s] behind the model are forgotten.
HISTORY_S = 5.0
#: Process time [s] the model steps before what it has passed is judged (> the longest step).
CHUNK_S = 2.0
#: Tool speed [share of movement.speed] above which the tool counts as moving (phases).
MOVING_SHARE = 0.1
#: The run's residuals are judged against the floor from this many windows into the run on.
RUN_WINDOWS = 2
#: Frames needed in the window before a state other than STALE is given.
MIN_FRAMES = 3

LEVELS = ("OK", "WARN", "ERROR")


@dataclass
class GapWatch(StreamIntake):
    """The model of ``model`` beside a running cell; see the module docstring."""

    model: CellParams
    floor: ResidualFloor
    settings: GapWatchNodeParams = field(default_factory=GapWatchNodeParams)

    def __post_init__(self) -> None:
        self._init_intake()
        self._next_wrench = 0                     # index of the first unjudged wrench sample
        self.sim: Simulation | None = None
        self.failed = ""
        self._hist: deque = deque()               # (t, nodes, tool force, touching)
        self._noise_p: deque = deque(maxlen=NOISE_SAMPLES)
        self._win_p: deque = deque()              # (t, sum r^2, n) per frame
        self._win_f: deque = deque()              # (t, sum r^2, n, |F meas|, |F model|)
        self._win_delta: deque = deque()          # (t, Delta measured - model [m], model [m])
        self.delta_diffs: list[float] = []        # m, Delta measured - model of every frame
        self.run_p, self.run_f = _Sums(), _Sums()
        self.phase_p = {p: _Sums() for p in PHASES}
        self.phase_f = {p: _Sums() for p in PHASES}
        self._phase = 0
        self._contact_seen = False
        self._dwell_seen = False
        self.peak_force = 0.0                     # N, the model's largest |tool force|
        self.judged_t = 0.0                       # s, newest judged time
        self.level = "STALE"
        self.reason = "no data yet"
        self._above_since: float | None = None
        self._error_since: float | None = None
        self.first_warn: float | None = None
        self.first_error: float | None = None
        self.trace: list[tuple] = []              # (t, zpw, zfw, zpr, zfr, F share, D share)
        self.cpu_s = 0.0                          # s, process time spent in update()
        self.model_nodes: np.ndarray | None = None   # the model's centreline now (N+2, 2) m
        s = self.model.solver
        self._full_dt = s.dt

    # -- the model --------------------------------------------------------------------------
    def _remember(self, t: float, nodes: np.ndarray, force: np.ndarray, touching: bool) -> None:
        self._hist.append((t, nodes, force, touching))
        while len(self._hist) > 2 and self._hist[1][0] < t - HISTORY_S:
            self._hist.popleft()
        self.model_nodes = nodes
        self.peak_force = max(self.peak_force, float(np.hypot(*force)))

    def _step_model(self, final: bool, until: float) -> bool:
        """Whole solver steps up to ``until`` [s] (at most the newest knot); whether it moved."""
        if self.failed or not self._knot_t:
            return False
        if self.sim is None:
            self.sim = Simulation(self.model, tool_start=self._knot_xz[0])
            self._remember(0.0, self.sim.nodes(), self.sim.tool_force(), False)
        last = self._knot_t[-1]
        t_avail = min(last, until)
        t_now = self.sim.state.t
        if t_avail <= t_now + 1e-9:
            return False
        # steps end where an offline run's would: the schedule runs one step beyond what is
        # taken (the last one to the final pose only when the streams have ended)
        horizon = t_avail if (final and t_avail >= last) else t_avail + self._full_dt
        dts, tools = self.sim.schedule(horizon, self.tool_at(horizon), self.tool_at)
        ends = t_now + np.cumsum(dts)
        n = int(np.searchsorted(ends, t_avail + 1e-9, side="right"))
        if n == 0:
            return False
        try:
            rec = self.sim.advance_path(dts[:n], tools[:n])
        except (ConvergenceError, FloatingPointError, ValueError) as exc:
            self.failed = f"the model's solver failed at t = {self.sim.state.t:.2f} s: {exc}"
            return False
        anchors = (self.sim.constants.anchor_top, self.sim.constants.anchor_bottom)
        contact = rec.contact[:, TOOL]
        for k in range(len(rec)):
            nodes = np.vstack((anchors[0], rec.x[k], anchors[1]))
            force = -contact[k].sum(axis=0)
            self._remember(float(rec.t[k]), nodes, force, bool(np.any(contact[k] != 0.0)))
        return True

    def _model_at(self, t: float):
        """(nodes, tool force, touching) of the model at ``t`` [s], linear between steps; None
        when ``t`` is no longer (or not yet) in the history."""
        h = self._hist
        if not h or t < h[0][0] - 1e-9 or t > h[-1][0] + 1e-9:
            return None
        ts = [e[0] for e in h]
        k = min(max(bisect.bisect_left(ts, t), 1), len(ts) - 1) if len(ts) > 1 else 0
        if len(ts) == 1:
            return h[0][1], h[0][2], h[0][3]
        (t0, n0, f0, c0), (t1, n1, f1, c1) = h[k - 1], h[k]
        w = 0.0 if t1 <= t0 else min(max((t - t0) / (t1 - t0), 0.0), 1.0)
        return (1 - w) * n0 + w * n1, (1 - w) * f0 + w * f1, c0 or c1

    # -- judging ----------------------------------------------------------------------------
    def _phase_at(self, t: float, touching: bool) -> int:
        """Index into PHASES of process time ``t`` (online: see the module docstring)."""
        speed = float(np.hypot(*(self.tool_at(t) - self.tool_at(t - POSE_WINDOW)))) / POSE_WINDOW
        moving = speed > MOVING_SHARE * self.model.movement.speed
        if touching:
            self._contact_seen = True
            if not moving:
                self._dwell_seen = True
                return 2
            return 3 if self._dwell_seen else 1
        return 4 if self._contact_seen else 0

    @property
    def profile_noise(self) -> float:
        """m, the camera points' noise (online estimate, at least ``min_profile_noise``)."""
        return max(mad_sigma(self._noise_p), self.settings.min_profile_noise)

    @property
    def force_noise(self) -> float:
        """N, the load cell's noise (online estimate, at least ``min_force_noise``)."""
        return max(mad_sigma(self._noise_f), self.settings.min_force_noise)

    def _judge_frame(self, frame: _Frame) -> bool:
        m = self._model_at(frame.t)
        if m is None:
            return False
        nodes, _, touching = m
        r = signed_distance(frame.points, nodes)
        d2 = r[:-2] - 2.0 * r[1:-1] + r[2:]
        self._noise_p.extend(d2.tolist())          # along the frame: the points' noise
        r2 = float(r @ r)
        self._win_p.append((frame.t, r2, r.size))
        self.run_p.add(r2, r.size)
        ph = self._phase_at(frame.t, touching)
        self._phase = ph
        self.phase_p[PHASES[ph]].add(r2, r.size)
        th = self.model.sheet.thickness
        dm, dmod = residual_gap(frame.points, th), residual_gap(nodes, th)
        if math.isfinite(dm) and math.isfinite(dmod):
            self._win_delta.append((frame.t, dm - dmod, dmod))
            self.delta_diffs.append(dm - dmod)
        self.judged_t = max(self.judged_t, frame.t)
        return True

    def _judge_wrenches(self, upto: float) -> None:
        i = self._next_wrench
        while i < len(self.wrench_t) and self.wrench_t[i] <= upto + 1e-12:
            t = self.wrench_t[i]
            m = self._model_at(t)
            i += 1
            if m is None:
                self.refused["wrench: older than the model's history (late)"] += 1
                continue
            _, fmod, touching = m
            meas = np.asarray(self.wrench_xz[i - 1])
            r = meas - fmod
            r2 = float(r @ r)
            self._win_f.append((t, r2, 2, float(np.hypot(*meas)), float(np.hypot(*fmod))))
            self.run_f.add(r2, 2)
            self.phase_f[PHASES[self._phase_at(t, touching)]].add(r2, 2)
            self.judged_t = max(self.judged_t, t)
        self._next_wrench = i

    def update(self, final: bool = False) -> list[str]:
        """Step the model as far as the poses reach and judge what it has passed; returns the
        state changes (``"WARN at 12.3 s: ..."``) it made.  ``final``: the streams have ended
        (the model steps to the last pose)."""
        if not self.started:
            return []
        c0 = time.process_time()
        events: list[str] = []
        self._knots()
        if final and self.pose_t and (not self._knot_t or self._knot_t[-1] < self.pose_t[-1]):
            lo = bisect.bisect_left(self.pose_t, self.pose_t[-1] - POSE_WINDOW / 2)
            self._knot_t.append(self.pose_t[-1])
            self._knot_xz.append(np.mean(np.asarray(self.pose_xz[lo:], float), axis=0))
        # in chunks of CHUNK_S, judging after each: a long queue taken at once never steps
        # the model past frames it has not judged yet (the model's history is HISTORY_S)
        while True:
            moved = self._step_model(final, (self.sim.state.t if self.sim else 0.0) + CHUNK_S)
            events += self._judge()
            if not moved:
                break
        if self.failed and self.level != "FAILED":
            self.level, self.reason = "FAILED", self.failed
            events.append(f"FAILED: {self.failed}")
        self.cpu_s += time.process_time() - c0
        return events

    def _judge(self) -> list[str]:
        """Judge the frames and forces the model has passed; the state changes."""
        events: list[str] = []
        if not self._hist:
            return events
        t_model = self._hist[-1][0]
        while self._pending_frames and self._pending_frames[0].t <= t_model + 1e-12:
            fr = self._pending_frames.popleft()
            if not self._judge_frame(fr):
                self.refused["profile: older than the model's history (late)"] += 1
                continue
            self._judge_wrenches(fr.t)
            events += self._evaluate(fr.t)
        self._judge_wrenches(t_model)
        return events

    # -- the state --------------------------------------------------------------------------
    def _window(self, t: float) -> tuple[_Sums, _Sums, float, float]:
        """Window sums (profile, force) and the ERROR shares (F_max, Delta) ending at ``t``."""
        lo = t - self.settings.window
        for q in (self._win_p, self._win_f, self._win_delta):
            while q and q[0][0] <= lo:
                q.popleft()
        wp, wf = _Sums(), _Sums()
        for e in self._win_p:
            if e[0] <= t:
                wp.add(e[1], e[2])
        f_share = 0.0
        for e in self._win_f:
            if e[0] <= t:
                wf.add(e[1], e[2])
        sf = self.force_noise
        if wf.n and self.peak_force > 10.0 * sf:
            f_share = wf.figures(sf)["systematic"] / self.peak_force
        d_share = 0.0
        dd = [e for e in self._win_delta if e[0] <= t]
        if len(dd) >= MIN_FRAMES:
            gap = float(np.median([e[1] for e in dd])) - getattr(self.floor, "delta_bias_m", 0.0)
            ref = float(np.median([e[2] for e in dd]))
            d_share = abs(gap) / ref if ref > 0 else 0.0
        return wp, wf, f_share, d_share

    def _evaluate(self, t: float) -> list[str]:
        if self.lost:
            if self.level != "STALE":
                self.level, self.reason = "STALE", self.lost
                return [f"STALE at {t:.1f} s: {self.lost}"]
            return []
        wp, wf, f_share, d_share = self._window(t)
        if sum(1 for e in self._win_p if e[0] <= t) < MIN_FRAMES:
            return []
        sp, sf = self.profile_noise, self.force_noise
        fl = self.floor
        zpw = wp.figures(sp)["z"]
        zfw = wf.figures(sf)["z"] if wf.n else None
        # the run's figures count once they hold RUN_WINDOWS windows (before, they are the
        # window's, with its spread)
        mature = t >= RUN_WINDOWS * self.settings.window
        zpr = self.run_p.figures(sp)["z"] if mature else None
        zfr = self.run_f.figures(sf)["z"] if self.run_f.n and mature else None
        self.trace.append((t, zpw, zfw, zpr, zfr, f_share, d_share))
        checks = (("profile (window)", zpw, fl.profile_window_z),
                  ("force (window)", zfw, fl.force_window_z),
                  ("profile (run)", zpr, fl.profile_run_z),
                  ("force (run)", zfr, fl.force_run_z))
        above = [f"{name} {z:.2f} > {lim:.2f}" for name, z, lim in checks
                 if z is not None and z > lim]
        share = self.settings.error_share
        shares = (("F_max (tool force)", f_share), ("Delta", d_share))
        big = [f"{name} {v:.0%}" for name, v in shares if v > share]
        self._above_since = (self._above_since if self._above_since is not None else t) \
            if above else None
        self._error_since = (self._error_since if self._error_since is not None else t) \
            if (big and above) else None
        sustain = self.settings.sustain
        level, reason = "OK", "the gap is within the floor"
        if self._above_since is not None and t - self._above_since >= sustain - 1e-9:
            level = "WARN"
            reason = (f"above the floor for {t - self._above_since:.1f} s: " + ", ".join(above))
            if self._error_since is not None and t - self._error_since >= sustain - 1e-9:
                level = "ERROR"
                reason = (f"the gap changes {', '.join(big)} (more than "
                          f"{share:.0%}) for {t - self._error_since:.1f} s; " + reason)
        events = []
        if level != self.level:
            events.append(f"{level} at {t:.1f} s: {reason}")
        if level in ("WARN", "ERROR") and self.first_warn is None:
            self.first_warn = t
        if level == "ERROR" and self.first_error is None:
            self.first_error = t
        self.level, self.reason = level, reason
        return events

    def residuals(self) -> dict:
        """The residuals now: noise, window, run and per phase (profile [m], force [N])."""
        sp, sf = self.profile_noise, self.force_noise
        t = self.judged_t
        wp, wf, f_share, d_share = self._window(t)

        def both(p: _Sums, f: _Sums) -> dict:
            return {"profile_m": p.figures(sp), "force_N": f.figures(sf)}
        return {"process_time_s": t,
                "model_time_s": self._hist[-1][0] if self._hist else 0.0,
                "newest_pose_s": self.pose_t[-1] if self.pose_t else 0.0,
                "noise": {"profile_m": sp, "force_N": sf},
                "window_s": self.settings.window,
                "window": both(wp, wf), "run": both(self.run_p, self.run_f),
                "phases": {p: both(self.phase_p[p], self.phase_f[p]) for p in PHASES
                           if self.phase_p[p].n or self.phase_f[p].n},
                "phase": PHASES[self._phase],
                "shares": {"F_max": f_share, "Delta": d_share},
                "floor": {"profile_window_z": self.floor.profile_window_z,
                          "force_window_z": self.floor.force_window_z,
                          "profile_run_z": self.floor.profile_run_z,
                          "force_run_z": self.floor.force_run_z},
                "refused": dict(self.refused), "first_refused_stamp_s": dict(self.first_refused)}

    def status(self) -> Status:
        return Status(self.level, self.reason, self.judged_t,
                      self._hist[-1][0] if self._hist else 0.0, self.residuals(),
                      self.first_warn, self.first_error)

    @property
    def ended(self) -> bool:
        """The model has reached the cell's process end (``movement.process_time``)."""
        return self.sim is not None and \
            self.sim.state.t >= self.model.movement.process_time - 1e-6

    # -- the record -------------------------------------------------------------------------
    def record(self, name: str = "gap_watch") -> Record:
        """The run so far (from the process start) as a record of the project's format; its
        scenario is the model cell."""
        # lengths taken once: another thread may be appending a sample meanwhile
        n, nw = min(len(self.pose_t), len(self.pose_xz)), min(len(self.wrench_t),
                                                              len(self.wrench_xz))
        pt = np.asarray(self.pose_t[:n], float)
        pxz = np.asarray(self.pose_xz[:n], float).reshape(-1, 2)
        if pt.size and pt[0] > 0.0:                   # t = 0 is the earliest pose stamp
            pt, pxz = np.r_[0.0, pt], np.vstack((pxz[:1], pxz))
        wt = np.asarray(self.wrench_t[:nw], float) if nw else None
        wxz = np.asarray(self.wrench_xz[:nw], float).reshape(-1, 2) if nw else None
        frames = list(self.frames)
        return Record(scenario=self.model, pose_t=pt, pose_xz=pxz,
                      profile_t=np.asarray([f.t for f in frames], float),
                      profiles=tuple(f.points for f in frames), wrench_t=wt,
                      wrench_xz=wxz, name=name)
