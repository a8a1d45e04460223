"""Model against measurement for one record: the residuals the diagnosis works on.

The model of a record is its scenario's cell (plus any effect under test)
driven by the MEASURED tool pose (the robot's report), smoothed and reduced
to a few knots (:func:`tool_path`).  A measured profile point's residual is
its signed normal distance [m] to the model's centreline polyline at the
frame's time (positive on the side of the polyline's left normal, i.e. away
from the mould for a sheet running from the cake top down to the workplane);
a force residual is measured minus model force on the tool [N], per axis.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sheet.metrics import residual_gap
from ..params.cell import CellParams
from ..records.record import Record
from ..sheet.paths import PolylinePath, ToolPath
from ..sheet.simulation import RunResult, run_scenario
from .initial_state import InitialState, estimate
from .kernel import project

#: Width [s] of the moving average applied to the measured pose before it drives the model.
POSE_WINDOW = 0.4
#: Tolerance [m] of the knot reduction of the smoothed pose (time counted at 1 mm/s).
PATH_TOLERANCE = 2e-5


def tool_path(record: Record) -> PolylinePath:
    """The measured tool pose, averaged over ``POSE_WINDOW`` and reduced to few knots."""
    t, xz = record.pose_t, record.pose_xz
    grid = np.arange(0.0, t[-1] + 1e-9, POSE_WINDOW / 2)
    if grid[-1] < t[-1]:
        grid = np.append(grid, t[-1])
    c = np.concatenate(([0.0], np.cumsum(xz, axis=0)[:, 0]))
    cz = np.concatenate(([0.0], np.cumsum(xz, axis=0)[:, 1]))
    lo = np.searchsorted(t, grid - POSE_WINDOW / 2)
    hi = np.maximum(np.searchsorted(t, grid + POSE_WINDOW / 2, side="right"), lo + 1)
    hi = np.minimum(hi, t.size)
    lo = np.minimum(lo, hi - 1)
    n = hi - lo
    pts = np.c_[(c[hi] - c[lo]) / n, (cz[hi] - cz[lo]) / n]
    keep = _simplify(np.c_[grid * 1e-3, pts], PATH_TOLERANCE)
    return PolylinePath(grid[keep], pts[keep])


def _simplify(points: np.ndarray, tol: float) -> np.ndarray:
    """Indices kept by Ramer-Douglas-Peucker on (K, D) points (iterative)."""
    keep = np.zeros(len(points), dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, len(points) - 1)]
    while stack:
        a, b = stack.pop()
        if b <= a + 1:
            continue
        seg = points[b] - points[a]
        rel = points[a + 1:b] - points[a]
        L2 = float(seg @ seg)
        s = np.clip(rel @ seg / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(rel))
        d = np.linalg.norm(rel - s[:, None] * seg, axis=1)
        i = int(np.argmax(d))
        if d[i] > tol:
            keep[a + 1 + i] = True
            stack += [(a, a + 1 + i), (a + 1 + i, b)]
    return np.flatnonzero(keep)


@dataclass(frozen=True)
class RecordData:
    """A record flattened for fast comparison (all profile points in one array)."""

    record: Record
    path: ToolPath             # the measured pose as a path (a replay: the planned one)
    point_xz: np.ndarray       # (P, 2) m, every measured profile point
    point_frame: np.ndarray    # (P,) index into profile_t
    last_frame: np.ndarray     # (M, 2) m, the last frame's points (Delta)
    initial: InitialState | None = None   # the sheet's state when the records begin

    @classmethod
    def of(cls, record: Record, initial: str = "settled") -> "RecordData":
        """``initial``: how the model's initial state is taken (:mod:`.initial_state`:
        ``settled``, the scenario's drape; ``laid``, the first frame released; ``auto``)."""
        pts = [np.asarray(f, float).reshape(-1, 2) for f in record.profiles]
        frame = np.concatenate([np.full(len(f), i)
                               for i, f in enumerate(pts)]) if pts else np.zeros(0, int)
        state = estimate(record, initial) if initial != "settled" else None
        return cls(record, tool_path(record), np.vstack(pts), frame.astype(int), pts[-1],
                   state)


@dataclass(frozen=True)
class Residuals:
    """Residuals of one record against one model run."""

    profile: np.ndarray        # (P,) m, signed normal distance of each measured point
    arc: np.ndarray            # (P,) m, arc length of its foot point on the model's centreline
    foot: np.ndarray           # (P, 2) m, the foot point
    force: np.ndarray | None   # (W, 2) N, measured - model force on the tool
    delta_measured: float      # m, Delta of the last measured frame
    delta_model: float         # m, Delta of the model at that time
    run: RunResult
    normal: np.ndarray | None = None   # (P, 2) unit left normal of the model at each foot point


def simulate(params: CellParams, data: RecordData) -> RunResult:
    """The model ``params`` driven by the record's measured tool pose, to the record's end
    (from the record's laid sheet when its initial state says so)."""
    laid = data.initial.laid(params) if data.initial is not None else None
    return run_scenario(params, data.path, t_end=data.record.duration, laid=laid)


def polylines_at(run: RunResult, times: np.ndarray) -> np.ndarray:
    """Model centrelines (F, N+2, 2) [m] at ``times`` [s], linear between solver steps."""
    nodes = np.concatenate((np.broadcast_to(run.anchors[0], (run.t.size, 1, 2)), run.x,
                            np.broadcast_to(run.anchors[1], (run.t.size, 1, 2))), axis=1)
    k = np.clip(np.searchsorted(run.t, times), 1, run.t.size - 1)
    t0, t1 = run.t[k - 1], run.t[k]
    w = np.clip((times - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0, 1.0)[:, None, None]
    return (1.0 - w) * nodes[k - 1] + w * nodes[k]


def residuals(data: RecordData, run: RunResult) -> Residuals:
    """Profile, force and Delta residuals of a record against a model run."""
    rec = data.record
    lines = polylines_at(run, rec.profile_t)                  # (F, K, 2)
    dist, arc, foot, normal = project(data.point_xz, data.point_frame, lines)
    force = None
    if rec.has_wrench:
        # every maker of a Record gives the forces with the stamps
        assert rec.wrench_t is not None and rec.wrench_xz is not None
        model = np.c_[np.interp(rec.wrench_t, run.t, run.tool_force[:, 0]),
                      np.interp(rec.wrench_t, run.t, run.tool_force[:, 1])]
        force = rec.wrench_xz - model
    th = rec.scenario.sheet.thickness
    return Residuals(dist, arc, foot, force, residual_gap(data.last_frame, th),
                     residual_gap(lines[-1], th), run, normal)


def noise_level(values: np.ndarray, groups: np.ndarray | None = None) -> float:
    """Robust std [same unit] of the white noise on a smooth signal: MAD of second differences.

    For white noise of std s, x[i-1] - 2 x[i] + x[i+1] has std s sqrt(6); a
    signal smooth on the sampling scale adds little.  ``groups`` (same length)
    keeps differences within a group (a frame).
    """
    v = np.asarray(values, float)
    d = v[:-2] - 2.0 * v[1:-1] + v[2:]
    if groups is not None:
        g = np.asarray(groups)
        d = d[(g[:-2] == g[1:-1]) & (g[1:-1] == g[2:])]
    if d.size < 5:
        return float("nan")
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(6.0))
