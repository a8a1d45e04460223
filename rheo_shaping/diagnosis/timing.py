"""Whose clock a lag is on: the load cell's, or the tool's, which the camera sees too.

A load cell that lags delays the measured force and nothing else.  A tool that follows
the pose it reports late (or a camera whose stamps run early) delays the profile as
well: the sheet the camera sees at t is the model's at t - tau.  So when the measurement
chain's hypothesis needs the load cell to lag beyond its tolerance, the profile's own
lag behind the model is measured at the baseline (:func:`profile_lag`), and the chain's
hypothesis is refused when the profile lags by at least ``PROFILE_SHARE`` of the force's
lag (:func:`lag_check`): the lag is then not the load cell's, and no library effect nor
chain knob holds a tool that lags its reported pose.

``PROFILE_SHARE`` = 1/4: at the baseline the sheet's viscous knobs absorb part of a pose
lag, while model form puts a little of a load-cell lag on the profile.  On the dynamic
world's seeds 26007 and 26008 (63 masses, 120 s; 31 masses, 70 s), where the check ran,
the profile's lag was 0.27-1.15 of the force's for 14 tool lags of 0.23-0.49 s (median
0.65) and 0.06-0.20 of it for 11 load-cell lags of 0.2-0.45 s (median 0.10); a quarter
is the geometric middle of the two medians (docs/diagnosis.md, "A lag: the load cell's,
or the tool's?").
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .baseline import CHAIN
from .compare import RecordData, polylines_at
from .evaluate import Outcome
from .kernel import project

#: The profile's lag, as a share of the force's, from which the lag is the tool's [-].
PROFILE_SHARE = 0.25
#: The shifts [s] the profile's lag is looked for on (then refined by a parabola).
LAG_GRID_S = np.round(np.arange(-0.25, 1.0001, 0.05), 10)

_LAG = [k.name for k in CHAIN].index("load_cell.lag")


def profile_misfit(data: Sequence[RecordData], outs: Sequence[Outcome],
                   shift_s: float) -> float:
    """Least sum of squared profile residuals [m^2] of records ``data`` against their model
    runs (``outs``' kept runs) taken ``shift_s`` [s] earlier, over one camera offset
    (dx, dz) [m] along the model's normals (a static offset and a lag of a sheet that moves
    one way look alike: they are fitted together)."""
    rs, ns = [], []
    for d, o in zip(data, outs):
        lines = polylines_at(o.kept_run, np.maximum(d.record.profile_t - shift_s, 0.0))
        dist, _arc, _foot, normal = project(d.point_xz, d.point_frame, lines)
        rs.append(dist)
        ns.append(normal)
    r, n = np.concatenate(rs), np.concatenate(ns)
    offset, *_ = np.linalg.lstsq(n, r, rcond=None)
    e = r - n @ offset
    return float(e @ e)


def profile_lag(data: Sequence[RecordData], outs: Sequence[Outcome]) -> float:
    """The lag [s] of the measured profiles behind the model runs of ``outs`` (kept runs):
    the shift of least profile misfit (:func:`profile_misfit`) on :data:`LAG_GRID_S`,
    refined by the parabola through it and its neighbours."""
    ss = np.array([profile_misfit(data, outs, float(s)) for s in LAG_GRID_S])
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
    tool's?  The profile's lag at the baseline's runs ``outs`` of the fit records ``data``
    against the force's; ``tool_lags`` when the profile lags by at least ``PROFILE_SHARE``
    of it."""
    force_lag = float(chain_u[_LAG]) * CHAIN[_LAG].tolerance
    p_lag = profile_lag(data, outs)
    tool = bool(force_lag > 0 and math.isfinite(p_lag) and p_lag >= PROFILE_SHARE * force_lag)
    return {"force_lag_s": force_lag, "profile_lag_s": p_lag,
            "profile_share": PROFILE_SHARE, "tool_lags": tool}
