"""Whose clock a lag is on: the load cell's, or the tool's, which the camera sees too.

A load cell that lags delays the measured force and nothing else.  A tool that follows
the pose it reports late (or a camera whose stamps run early) delays the profile as
well: the sheet the camera sees at t is the model's at t - tau.  So when the measurement
chain's hypothesis needs the load cell to lag beyond its tolerance, the profile's own
lag behind the model is measured at the baseline (:func:`profile_lag`), and the chain's
hypothesis is refused when the profile lags by at least ``PROFILE_SHARE`` of the force's
lag (:func:`lag_check`): the lag is then not the load cell's, and no library effect nor
chain knob holds a tool that lags its reported pose.

The profile's lag is measured on the frames the tool drives (``DRIVEN``: forced
deformation, dwell, release; :func:`where.phases`), where a tool's lag acts.  Before the
tool touches, a laid sheet settles and creeps onto the mould at its own pace, which the
model's form follows a little early or late.  On the dynamic world's seeds 26013-26015
(63 masses, 120 s; 31 masses, 70 s) the profile lagged over every frame by 0.02-0.11 s in
18 load-cell-lag cases (up to 0.31 of the force's lag) and 0.024-0.026 s in 12 effect-free
ones; over the driven frames by -0.15 to +0.03 s (at most 0.10 of the force's lag) and
-0.04 to +0.02 s, while 18 tool lags of 0.21-0.47 s gave 0.10-0.47 s (0.75-1.13 of the
force's lag where the check ran).  The two hypotheses predict a share of 1 (the tool's lag
is the profile's) and 0 (the load cell's is not): ``PROFILE_SHARE`` = 1/2 lies between
them (docs/diagnosis.md, "A lag: the load cell's, or the tool's?").
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .baseline import CHAIN
from .compare import RecordData, polylines_at
from .evaluate import Outcome
from .kernel import project
from .where import PHASES, phases

#: The profile's lag, as a share of the force's, from which the lag is the tool's [-].
PROFILE_SHARE = 0.5
#: The phases whose frames the tool drives (indices into :data:`where.PHASES`).
DRIVEN = tuple(PHASES.index(p) for p in ("forced deformation", "dwell", "release"))
#: The shifts [s] the profile's lag is looked for on (then refined by a parabola).
LAG_GRID_S = np.round(np.arange(-0.25, 1.0001, 0.05), 10)

_LAG = [k.name for k in CHAIN].index("load_cell.lag")


def driven_points(d: RecordData, out: Outcome) -> np.ndarray:
    """Which of record ``d``'s profile points lie in frames the tool drives (:data:`DRIVEN`,
    from the model run ``out``'s tool contact)."""
    return np.isin(phases(d, out.kept_run)[d.point_frame], DRIVEN)


def profile_misfit(data: Sequence[RecordData], outs: Sequence[Outcome],
                   shift_s: float, points: Sequence[np.ndarray] | None = None) -> float:
    """Least sum of squared profile residuals [m^2] of records ``data`` against their model
    runs (``outs``' kept runs) taken ``shift_s`` [s] earlier, over one camera offset
    (dx, dz) [m] along the model's normals (a static offset and a lag of a sheet that moves
    one way look alike: they are fitted together); ``points``: each record's points to
    count (boolean masks; all when None)."""
    rs, ns = [], []
    for k, (d, o) in enumerate(zip(data, outs)):
        lines = polylines_at(o.kept_run, np.maximum(d.record.profile_t - shift_s, 0.0))
        sel = points[k] if points is not None else slice(None)
        dist, _arc, _foot, normal = project(d.point_xz[sel], d.point_frame[sel], lines)
        rs.append(dist)
        ns.append(normal)
    r, n = np.concatenate(rs), np.concatenate(ns)
    offset, *_ = np.linalg.lstsq(n, r, rcond=None)
    e = r - n @ offset
    return float(e @ e)


def profile_lag(data: Sequence[RecordData], outs: Sequence[Outcome],
                driven: bool = True) -> float:
    """The lag [s] of the measured profiles behind the model runs of ``outs`` (kept runs):
    the shift of least profile misfit (:func:`profile_misfit`) on :data:`LAG_GRID_S`,
    refined by the parabola through it and its neighbours; over the frames the tool drives
    (``driven``, :func:`driven_points`) or all of them.  NaN when the tool drives none."""
    points = [driven_points(d, o) for d, o in zip(data, outs)] if driven else None
    if points is not None and not any(p.any() for p in points):
        return math.nan
    ss = np.array([profile_misfit(data, outs, float(s), points) for s in LAG_GRID_S])
    k = int(np.argmin(ss))
    if 0 < k < ss.size - 1:
        y0, y1, y2 = ss[k - 1], ss[k], ss[k + 1]
        curv = y0 - 2.0 * y1 + y2
        if curv > 0:
            h = float(LAG_GRID_S[1] - LAG_GRID_S[0])
            return float(LAG_GRID_S[k] + 0.5 * h * (y0 - y2) / curv)
    return float(LAG_GRID_S[k])


def lag_check(data: Sequence[RecordData], outs: Sequence[Outcome],
              chain_u: np.ndarray) -> dict:
    """Is the chain's load-cell lag (``chain_u``, the chain's knobs in tolerances) the
    tool's?  The profile's lag over the frames the tool drives, at the baseline's runs
    ``outs`` of the fit records ``data``, against the force's; ``tool_lags`` when the
    profile lags by at least ``PROFILE_SHARE`` of it (never when the tool drives no frame:
    nothing then tells the two apart, and the chain's reading stands)."""
    force_lag = float(chain_u[_LAG]) * CHAIN[_LAG].tolerance
    p_lag = profile_lag(data, outs)
    tool = bool(force_lag > 0 and math.isfinite(p_lag) and p_lag >= PROFILE_SHARE * force_lag)
    return {"force_lag_s": force_lag, "profile_lag_s": p_lag,
            "profile_share": PROFILE_SHARE, "tool_lags": tool}
