"""The gap watch's intake: the cell's streams as they arrive, each sample checked and
timed on the process clock, or refused with a reason (never an exception); the tool pose
smoothed for the model (:mod:`.watch`, whose :class:`~.watch.GapWatch` this is a part of).

Samples are refused, each with a reason counted in :attr:`StreamIntake.refused`
(never an exception): a non-finite value, a position beyond :data:`MAX_POSITION` or a
force beyond :data:`MAX_FORCE`, a stamp that goes back, a stamp more
than ``max_stamp_jump`` beyond the newest pose (or before the start), a frame
with fewer than 3 or more than ``max_points`` points.  A pose stream that goes on
after a gap longer than ``max_stamp_jump`` (``RESUME_POSES`` poses in a row, each
following the one before) is taken up again and the gap bridged, so an outage of
the cell's stream never locks the watch out; after a gap longer than ``LOST_JUMPS``
``max_stamp_jump`` the run is no longer judged (STALE, with the span lost): the
model's tool crossed it on a straight line, the cell's may not have.
Times are stamps in seconds on the cell's clock; process time is seconds since
:meth:`StreamIntake.start`.
"""
from __future__ import annotations

import bisect
import math
from collections import Counter, deque
from dataclasses import dataclass

import numpy as np

from ..diagnosis.compare import POSE_WINDOW
from ..params.gapwatch_params import GapWatchNodeParams

#: Largest coordinate [m] of a tool pose or a profile point taken: a cell is metres across
#: (a pose at 1e300 m sent the model into a loop it never left, its queue growing to 1 GB).
MAX_POSITION = 10.0
#: Largest force component [N] of a tool wrench taken (a sheet breaks near 1 N).
MAX_FORCE = 1e4

#: Second differences kept for the online noise estimates (per observable).
NOISE_SAMPLES = 20000
#: Poses in a row beyond max_stamp_jump (each following the one before) after which the
#: stream counts as resumed after a gap (a real outage), not as stamps of another clock.
RESUME_POSES = 10
#: A gap in the tool pose longer than this many max_stamp_jump leaves the run unjudged (STALE):
#: the model's tool crossed it on a straight line, the cell's may not have.
LOST_JUMPS = 3


@dataclass
class _Frame:
    t: float                # s, process time
    points: np.ndarray      # (M, 2) m


class StreamIntake:
    """The samples of one run: tool poses, camera frames and tool forces on process time
    [s since :meth:`start`], what was refused and why, the smoothed tool pose."""

    settings: GapWatchNodeParams

    def _init_intake(self) -> None:
        self.t0: float | None = None              # stamp [s] of process time 0
        self.refused: Counter = Counter()         # reason -> count
        self._jumped: list[float] = []            # poses in a row beyond max_stamp_jump
        self._resumed_from = 0.0                  # s, the first pose after the newest gap
        self.lost = ""                            # why the run is no longer judged
        self.first_refused: dict[str, float] = {}  # reason -> the first refused stamp [s]
        self.pose_t: list[float] = []             # process time [s]
        self.pose_xz: list[tuple[float, float]] = []
        self.frames: list[_Frame] = []            # every accepted frame (for the record)
        self.wrench_t: list[float] = []
        self.wrench_xz: list[tuple[float, float]] = []
        self._pending_frames: deque[_Frame] = deque()
        self._noise_f: deque = deque(maxlen=NOISE_SAMPLES)   # force second differences [N]
        self._knot_t: list[float] = []            # smoothed tool pose knots (process time)
        self._knot_xz: list[np.ndarray] = []

    # -- the start --------------------------------------------------------------------------
    @property
    def started(self) -> bool:
        return self.t0 is not None

    def start(self, stamp: float) -> None:
        """Process time 0 is ``stamp`` [s] (the planner's plan start); before it, samples are
        the cell at rest and are not kept."""
        self.t0 = float(stamp)

    def _refuse(self, reason: str, stamp: float | None = None) -> str:
        self.refused[reason] += 1
        if stamp is not None and reason not in self.first_refused:
            self.first_refused[reason] = stamp
        return reason

    def _time(self, topic: str, stamp: float, last: float | None) -> float | str:
        """Process time of ``stamp`` or the reason it is refused."""
        if not math.isfinite(stamp):
            return self._refuse(f"{topic}: non-finite stamp")
        if self.t0 is None:
            if topic != "pose":
                return self._refuse(f"{topic}: before the first pose")
            self.start(stamp)
        t0 = self.t0
        assert t0 is not None           # start() sets it
        t = stamp - t0
        if t < -1e-9:
            return self._refuse(f"{topic}: stamp before the process start", stamp)
        t = max(t, 0.0)
        ref = self.pose_t[-1] if self.pose_t else 0.0
        if t > ref + self.settings.max_stamp_jump:
            if topic == "pose" and self._resumes(t):
                self.first_refused.setdefault("pose: the stream resumed after a gap (bridged)",
                                              stamp)
                self.refused["pose: the stream resumed after a gap (bridged)"] += 1
                first = self._resumed_from
                if first - ref > LOST_JUMPS * self.settings.max_stamp_jump:
                    self.lost = (f"the tool pose was lost from {ref:.1f} s to {first:.1f} s: the "
                                 f"model's sheet no longer follows the cell's; judged again at "
                                 f"the next run")
            else:
                return self._refuse(f"{topic}: stamp more than max_stamp_jump after the newest "
                                    f"pose", stamp)
        if last is not None and t <= last:
            return self._refuse(f"{topic}: stamp not after the previous one")
        if t > self.settings.max_record:
            return self._refuse(f"{topic}: beyond max_record")
        return t

    def _resumes(self, t: float) -> bool:
        """Whether a pose beyond ``max_stamp_jump`` continues a stream that has gone on after a
        gap (``RESUME_POSES`` such poses in a row, each within ``max_stamp_jump`` after the
        one before) rather than being a lone stamp from another clock; the gap is then
        bridged (the model's tool moves linearly across it)."""
        last = self._jumped[-1] if self._jumped else None
        if last is None or not (last < t <= last + self.settings.max_stamp_jump):
            self._jumped = [t]
            return False
        self._jumped.append(t)
        if len(self._jumped) >= RESUME_POSES:
            self._resumed_from = self._jumped[0]
            self._jumped = []
            return True
        return False

    # -- the inputs -------------------------------------------------------------------------
    def pose(self, stamp: float, x: float, z: float) -> str | None:
        """A tool pose (x, z) [m] at ``stamp`` [s]; the reason when refused."""
        if not (math.isfinite(x) and math.isfinite(z)):
            return self._refuse("pose: non-finite position")
        if max(abs(x), abs(z)) > MAX_POSITION:
            return self._refuse(f"pose: farther than {MAX_POSITION:g} m from the origin")
        t = self._time("pose", stamp, self.pose_t[-1] if self.pose_t else None)
        if isinstance(t, str):
            return t
        self.pose_t.append(t)
        self.pose_xz.append((float(x), float(z)))
        return None

    def profile(self, stamp: float, points) -> str | None:
        """A camera frame (M, 2) [m] at ``stamp`` [s], top bond to workplane bond."""
        try:
            pts = np.asarray(points, dtype=float).reshape(-1, 2)
        except (TypeError, ValueError):
            return self._refuse("profile: not a list of (x, z) points")
        if not 3 <= len(pts) <= self.settings.max_points:
            return self._refuse("profile: fewer than 3 or more than max_points points")
        if not np.all(np.isfinite(pts)):
            return self._refuse("profile: non-finite point")
        if np.max(np.abs(pts)) > MAX_POSITION:
            return self._refuse(f"profile: a point farther than {MAX_POSITION:g} m from the "
                                f"origin")
        t = self._time("profile", stamp, self.frames[-1].t if self.frames else None)
        if isinstance(t, str):
            return t
        frame = _Frame(t, pts)
        self.frames.append(frame)
        self._pending_frames.append(frame)
        return None

    def wrench(self, stamp: float, fx: float, fz: float) -> str | None:
        """The force of the sheet on the tool (fx, fz) [N] at ``stamp`` [s]."""
        if not (math.isfinite(fx) and math.isfinite(fz)):
            return self._refuse("wrench: non-finite force")
        if max(abs(fx), abs(fz)) > MAX_FORCE:
            return self._refuse(f"wrench: a force beyond {MAX_FORCE:g} N")
        t = self._time("wrench", stamp, self.wrench_t[-1] if self.wrench_t else None)
        if isinstance(t, str):
            return t
        self.wrench_t.append(t)
        self.wrench_xz.append((float(fx), float(fz)))
        n = len(self.wrench_t)
        if n >= 3:
            a, b, c = self.wrench_xz[-3:]
            for k in (0, 1):
                self._noise_f.append(a[k] - 2.0 * b[k] + c[k])
        return None

    # -- the tool pose, smoothed ----------------------------------------------------------
    def _knots(self) -> None:
        """Smoothed tool pose knots every POSE_WINDOW / 2 whose window the poses cover."""
        h = POSE_WINDOW / 2
        if not self.pose_t:
            return
        newest = self.pose_t[-1]
        while True:
            g = len(self._knot_t) * h
            if g + h > newest:
                return
            lo = bisect.bisect_left(self.pose_t, g - h)
            hi = bisect.bisect_right(self.pose_t, g + h)
            if hi <= lo:                                  # a gap in the poses: bridge it
                k = min(max(lo, 1), len(self.pose_t)) - 1
                xz = np.asarray(self.pose_xz[k], float)
            else:
                xz = np.mean(np.asarray(self.pose_xz[lo:hi], float), axis=0)
            self._knot_t.append(g)
            self._knot_xz.append(xz)

    def tool_at(self, t: float) -> np.ndarray:
        """The smoothed measured tool pose [m] at process time ``t`` (held beyond the knots)."""
        kt = self._knot_t
        if t <= kt[0]:
            return self._knot_xz[0].copy()
        if t >= kt[-1]:
            return self._knot_xz[-1].copy()
        k = bisect.bisect_right(kt, t)
        w = (t - kt[k - 1]) / (kt[k] - kt[k - 1])
        return (1.0 - w) * self._knot_xz[k - 1] + w * self._knot_xz[k]
