"""Fig. 18's sweep as data: movement 4's F_max and force peaks against the tool's distance
d [m] from the cake, and where F_max is smallest (the runs: :mod:`.reproduce`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np


@dataclass
class Sweep:
    """Fig. 18: movement 4 against the tool's distance d [m] from the cake."""

    d: np.ndarray            # (M,) m
    F_max: np.ndarray        # (M,) N
    peak1: np.ndarray        # (M,) N, vertical step (with its stop)
    peak2: np.ndarray        # (M,) N, horizontal step (with its stop)
    delta: np.ndarray        # (M,) m
    d_opt: float             # m, where F_max is smallest (parabola through the three best points)
    F_opt: float             # N, F_max there (from the parabola)
    interior: bool           # the minimum lies inside the range, not at an end
    i_min: int               # index of the smallest sampled F_max

    @property
    def peak_gap_at_min(self) -> float:
        """|peak1 - peak2| / F_max at the best sampled d: (nearly) 0 where the peaks are equal."""
        i = self.i_min
        return float(abs(self.peak1[i] - self.peak2[i]) / self.F_max[i])


def sweep_of(rows: Sequence[dict]) -> Sweep:
    """The sweep of rows {d [m], F_max, peak1, peak2 [N], delta [m]}, in any order."""
    rows = sorted(rows, key=lambda r: r["d"])
    d = np.array([r["d"] for r in rows])
    F = np.array([r["F_max"] for r in rows])
    d_opt, F_opt, interior, i = parabolic_minimum(d, F)
    return Sweep(d=d, F_max=F, peak1=np.array([r["peak1"] for r in rows]),
                 peak2=np.array([r["peak2"] for r in rows]),
                 delta=np.array([r["delta"] for r in rows]),
                 d_opt=d_opt, F_opt=F_opt, interior=interior, i_min=i)


def parabolic_minimum(x: np.ndarray, y: np.ndarray) -> tuple[float, float, bool, int]:
    """Smallest y of samples (x, y): (x*, y*, interior, index) with a parabola through the best
    three."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    i = int(np.argmin(y))
    if i == 0 or i == x.size - 1:
        return float(x[i]), float(y[i]), False, i
    xs, ys = x[i - 1:i + 2], y[i - 1:i + 2]
    a, b, c = np.polyfit(xs, ys, 2)
    if a <= 0.0:
        return float(x[i]), float(y[i]), True, i
    xm = float(np.clip(-b / (2.0 * a), xs[0], xs[-1]))
    return xm, float(np.polyval((a, b, c), xm)), True, i
