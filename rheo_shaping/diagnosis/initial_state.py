"""The model's state at the first frame, from the records (issue 26, point 2).

The sheet model starts, by default, from the scenario's drape settled before
t = 0 (docs/model.md, Initial state).  A real sheet is laid on the cake and
let go; when the records begin with that release, the first seconds show it
falling and creeping onto the mould, and the plastic flow of that phase stays
in the sheet for the whole run.  No knob of a settled drape reproduces that.

This module reads, from a record alone:

* the first profile frame's shape, smoothed (a local quadratic in arc length
  over +-``SMOOTH_HALF_WIDTH``), from the cake-top bond to the workplane bond:
  the laid sheet;
* its length bond to bond (the links' rest length when the sheet was laid
  without strain), with its standard error from the profile noise (a
  parametric bootstrap of the smoothing; measured on the dynamic world's
  camera, 0.2 mm every 3 mm: bias -0.04 to -0.10 mm, spread 0.15-0.19 mm);
* when the tool first comes within ``CONTACT_GAP`` of the measured sheet
  (pose and tool outline against the frames): the frames before it are the
  approach, which no tool effect touches;
* how far the sheet moves between its first frame and the last frame before
  contact (or, when the tool touches sooner, the first frame ``COMPARE_AFTER``
  later), in units of the profile noise (``motion``: the median distance of
  the points farther than ``TOOL_CLEAR`` from the tool).

``mode`` is ``laid`` when the sheet moves beyond ``MOVING`` noise units before
the tool touches (it was released when the records begin) and ``settled``
otherwise (the scenario's settled drape, as before).  A laid record's model
starts at the first frame's time, at rest in the laid shape with unstretched
links of the measured length (plus ``sheet.excess_length`` minus its written
value: the baseline's sag knob becomes the laid strain), and takes inertial
steps for the first ``RELEASE_TIME`` (:class:`~rheo_shaping.sheet.simulation.LaidSheet`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..params.cell import CellParams
from ..records.record import Record
from ..sheet.drape import make_drape
from ..sheet.geometry import Cake, Workplane
from ..sheet.simulation import LaidSheet
from ..sheet.tools import tool_shape

#: How a record's initial state is taken (``diagnose --initial-state``).
MODES = ("auto", "laid", "settled")
#: Motion [noise units] of one record beyond which ``auto`` takes every record as laid,
#: whatever the others show (a sheet laid over a tool in its way falls far when let go, while
#: a sheet laid close to the mould may hardly move in the other records: seen 27 against
#: 1.2-1.5).  A settled sheet moves 0.35-1.67 (noise and the approach's creep).
CLEARLY_MOVING = 10.0
#: Half width [m] of the local quadratic that smooths the first frame along its arc length.
SMOOTH_HALF_WIDTH = 9e-3
#: Motion [profile noise units: median distance of the first frame's points from a later
#: frame's smoothed line] beyond which the sheet was released when the records begin
#: (``auto``).  Noise alone gives about 0.7-0.9.
MOVING = 2.5
#: Distance [m] of the tool's outline from the measured centreline, beyond the sheet's
#: half thickness, below which the tool counts as touching.
CONTACT_GAP = 1e-3
#: Points nearer than this [m] to the tool's outline do not count in the motion (the tool,
#: not the release, moves them).
TOOL_CLEAR = 1e-2
#: The first frame is compared with a frame at least this much later [s].
COMPARE_AFTER = 1.5
#: Inertial steps [s] after the release (the fall and its ringing; docs/diagnosis.md).
RELEASE_TIME = 1.5
#: Bootstrap replicates of the smoothing for the length's standard error.
BOOT = 24


@dataclass(frozen=True)
class InitialState:
    """What the records say about the sheet's state when they begin."""

    mode: str                   # "laid" (released when the records begin) or "settled"
    t0: float                   # s, time of the first frame (the release, for a laid sheet)
    shape: np.ndarray = field(repr=False, compare=False)   # (M, 2) m, first frame, smoothed
    length: float = math.nan    # m, laid length bond to bond (written bonds)
    length_sd: float = math.nan  # m, its standard error from the profile noise
    noise: float = math.nan     # m, the profile noise of the frames before contact
    motion: float = 0.0         # noise units: median change from the first frame to a later
    #                             one (_comparison_frame)
    contact_time: float = math.nan   # s, first frame in which the tool touches the sheet
    written_excess: float = 0.0      # m, the scenario's sheet.excess_length
    ends: float = 0.0           # m, the pieces of ``length`` from the written bonds to the
    #                             first and last point
    offset: float = 0.0         # m, the rest length's offset fitted on the record's first
    #                             seconds (:mod:`.laid_length`)

    def laid(self, params: CellParams) -> LaidSheet | None:
        """The model's laid sheet for cell ``params`` (bonds, cake, the sag knob's offset from
        its written value as laid strain), or None for a settled record."""
        if self.mode != "laid":
            return None
        s, c = params.sheet, params.cake
        r = 0.5 * s.thickness
        top = np.array([s.top_bond_x, c.height + r])
        bottom = np.array([s.bottom_bond_x, r])
        nodes = push_out(np.vstack((top, self.shape, bottom)), params)
        nodes[0], nodes[-1] = top, bottom
        rest = self.rest(params)
        return LaidSheet(nodes, rest, self.t0, RELEASE_TIME)

    def rest(self, params: CellParams) -> float:
        """The links' total rest length [m] for cell ``params``: the record's laid length
        with the cell's bonds (the pieces from each bond to the first and last measured
        point follow the bond knobs), plus the sag knob's offset from its written value
        (the strain the sheet was laid with, common to the records), plus the record's own
        ``offset`` (its first seconds' fit, :mod:`.laid_length`)."""
        s, c = params.sheet, params.cake
        r = 0.5 * s.thickness
        ends = (float(np.hypot(*(self.shape[0] - [s.top_bond_x, c.height + r])))
                + float(np.hypot(*(self.shape[-1] - [s.bottom_bond_x, r]))))
        return (self.length - self.ends + ends + (s.excess_length - self.written_excess)
                + self.offset)

    def as_dict(self) -> dict:
        """Plain numbers for the report and JSON (SI units)."""
        return {"mode": self.mode, "t0_s": self.t0, "laid_length_m": self.length,
                "laid_length_sd_m": self.length_sd, "motion_noise_units": self.motion,
                "contact_time_s": (self.contact_time if math.isfinite(self.contact_time)
                                   else None), "profile_noise_m": self.noise,
                "rest_length_offset_m": self.offset}


def rest_length(params: CellParams) -> float:
    """The sheet's rest length [m] as the scenario gives it (the drape's length with
    ``sheet.excess_length``: the baseline's knobs move it, one value for every record)."""
    s, c = params.sheet, params.cake
    return float(make_drape(c.height, c.fillet_radius, 0.5 * s.thickness, s.top_bond_x,
                            s.bottom_bond_x, s.excess_length).length)


def push_out(nodes: np.ndarray, params: CellParams) -> np.ndarray:
    """``nodes`` (M, 2) [m] moved out of cake and workplane to a clearance of half the
    sheet's thickness (what the measurement noise put inside)."""
    r = 0.5 * params.sheet.thickness
    out = np.array(nodes, float)
    for region in (Cake.of(params.cake), Workplane()):
        d, n = region.signed_distance(out)
        inside = d < r
        out[inside] += (r - d[inside])[:, None] * n[inside]
    return out


def _arc(pts: np.ndarray) -> np.ndarray:
    return np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))))


def smooth(pts: np.ndarray, half_width: float = SMOOTH_HALF_WIDTH) -> np.ndarray:
    """Points (M, 2) [m] of one frame smoothed by a local quadratic in arc length (each point
    from its neighbours within +-``half_width``, tricube weights)."""
    s = _arc(pts)
    out = np.empty_like(pts)
    for i, si in enumerate(s):
        sel = np.abs(s - si) <= half_width
        if np.count_nonzero(sel) < 4:
            out[i] = pts[i]
            continue
        u = (s[sel] - si) / half_width
        w = (1.0 - np.abs(u) ** 3) ** 3 + 1e-6
        V = np.c_[np.ones_like(u), u, u * u] * np.sqrt(w)[:, None]
        coef, *_ = np.linalg.lstsq(V, pts[sel] * np.sqrt(w)[:, None], rcond=None)
        out[i] = coef[0]
    return out


def laid_length(shape: np.ndarray, top: np.ndarray, bottom: np.ndarray) -> float:
    """Length [m] of the polyline bond, ``shape``, bond."""
    return float(_arc(np.vstack((top, shape, bottom)))[-1])


def profile_noise(frames: list[np.ndarray]) -> float:
    """Profile noise [m]: MAD of the second differences of the points' coordinates within
    each frame / sqrt(6) (the sheet's curvature over 2 point spacings is a small part)."""
    d = [f[:-2] - 2.0 * f[1:-1] + f[2:] for f in frames if len(f) >= 3]
    if not d:
        return math.nan
    v = np.concatenate(d).ravel()
    return float(1.4826 * np.median(np.abs(v - np.median(v))) / math.sqrt(6.0))


def distance_to(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Unsigned distance [m] of each of ``points`` (P, 2) to polyline ``line`` (K, 2)."""
    a, seg = line[:-1], np.diff(line, axis=0)
    L2 = np.maximum(np.einsum("sk,sk->s", seg, seg), 1e-300)
    rel = points[:, None, :] - a[None]
    t = np.clip(np.einsum("psk,sk->ps", rel, seg) / L2, 0.0, 1.0)
    d = rel - t[..., None] * seg[None]
    return np.sqrt(np.min(np.einsum("psk,psk->ps", d, d), axis=1))


def contact_time(record: Record) -> float:
    """Time [s] of the first frame in which the tool's outline (the pose's reference point)
    comes within half a thickness plus ``CONTACT_GAP`` of a measured point; inf if never."""
    sc = record.scenario
    shape = tool_shape(sc.tool)
    r = 0.5 * sc.sheet.thickness
    for t, f in zip(record.profile_t, record.profiles):
        pts = np.asarray(f, float).reshape(-1, 2)
        if len(pts) == 0:
            continue
        pose = [float(np.interp(t, record.pose_t, record.pose_xz[:, k])) for k in (0, 1)]
        d, _ = shape.signed_distance(pts, pose)
        if float(np.min(d)) < r + CONTACT_GAP:
            return float(t)
    return math.inf


def pool(states: list[InitialState | None], auto: bool = False) -> list[InitialState | None]:
    """The records' initial states read together.  ``auto``: one mode for all, ``laid`` when
    the records' median motion exceeds ``MOVING`` (the same cell, laid the same way; one
    record alone can move little) or one record's exceeds ``CLEARLY_MOVING``.  Each laid
    record keeps its own length: no two layings need be of one length (a sheet laid over a
    tool in its way is laid longer), and what the first frame misses, each record's first
    seconds fit (:mod:`.laid_length`)."""
    if auto and any(s is not None for s in states):
        motions = [s.motion for s in states if s is not None]
        moving = float(np.median(motions)) > MOVING or max(motions) > CLEARLY_MOVING
        states = [None if s is None else replace(s, mode="laid" if moving else "settled")
                  for s in states]
    return states


def _comparison_frame(usable: list[int], times: np.ndarray, before: list[int],
                      i0: int) -> int | None:
    """The frame the first one is compared with: the last before the tool touches when that
    is ``COMPARE_AFTER`` or more after the first, else the first that late (the tool may
    start against the sheet; the fall moves all of it, the tool only where it touches)."""
    if before and times[before[-1]] >= times[i0] + COMPARE_AFTER:
        return before[-1]
    late = [i for i in usable if times[i] >= times[i0] + COMPARE_AFTER]
    return late[0] if late else None


def estimate(record: Record, mode: str = "auto", seed: int = 0) -> InitialState:
    """The initial state of ``record``'s sheet (see the module's docstring); ``mode``:
    ``auto`` (laid when the sheet moves before contact), ``laid`` or ``settled``."""
    if mode not in MODES:
        raise ValueError(f"initial state {mode!r}: expected one of {', '.join(MODES)}")
    sc = record.scenario
    frames = [np.asarray(f, float).reshape(-1, 2) for f in record.profiles]
    times = np.asarray(record.profile_t, float)
    usable = [i for i, f in enumerate(frames) if len(f) >= 5]
    if not usable:
        raise ValueError(f"record '{record.name}': no profile frame with 5 points or more, "
                         "so its initial state cannot be read")
    i0 = usable[0]
    t_c = contact_time(record)
    before = [i for i in usable if times[i] < t_c]
    noise = profile_noise([frames[i] for i in (before or usable[:1])])
    r = 0.5 * sc.sheet.thickness
    top = np.array([sc.sheet.top_bond_x, sc.cake.height + r])
    bottom = np.array([sc.sheet.bottom_bond_x, r])
    shape = smooth(frames[i0])
    length = laid_length(shape, top, bottom)
    # the length's spread under the profile noise: a parametric bootstrap of the smoothing
    rng = np.random.default_rng(seed)
    boot = np.array([laid_length(smooth(shape + rng.normal(0.0, noise, shape.shape)), top, bottom)
                     for _ in range(BOOT)]) if noise > 0 else np.array([length])
    motion = 0.0
    later = _comparison_frame(usable, times, before, i0)
    if later is not None and noise > 0:
        pts = frames[i0]
        far = np.ones(len(pts), dtype=bool)        # away from the tool at both times
        shape_t = tool_shape(sc.tool)
        for i in (i0, later):
            pose = [float(np.interp(times[i], record.pose_t, record.pose_xz[:, k]))
                    for k in (0, 1)]
            far &= shape_t.signed_distance(pts, pose)[0] > TOOL_CLEAR
        if np.count_nonzero(far) >= 5:
            d = distance_to(pts[far], smooth(frames[later]))
            motion = float(np.median(d)) / noise
    chosen = mode if mode != "auto" else ("laid" if motion > MOVING else "settled")
    ends = (float(np.hypot(*(shape[0] - top))) + float(np.hypot(*(shape[-1] - bottom))))
    return InitialState(chosen, float(times[i0]), shape, length, float(np.std(boot)),
                        noise, motion, t_c, float(sc.sheet.excess_length), ends=ends)


def initial_summary(data, choice: dict | None = None) -> dict:
    """How the records' models started: the common mode and each record's reading;
    ``choice``: the baselines' misfits J of the fit records from either start, when ``auto``
    read the records as settled and compared the two ({"settled_J", "laid_J"})."""
    states = {d.record.name: d.initial for d in data}
    modes = {s.mode if s is not None else "settled" for s in states.values()}
    out = {"mode": modes.pop() if len(modes) == 1 else "mixed",
           "records": {n: (s.as_dict() if s is not None else {"mode": "settled"})
                       for n, s in states.items()}}
    if choice is not None:
        out["compared"] = dict(choice)
    return out
