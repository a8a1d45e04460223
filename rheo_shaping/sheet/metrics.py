"""Quality and safety figures of a shaping run (paper Sec. 5, Table 2)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PeakTension:
    """Largest link tension of a run: F_max [N], which link (1 = top) and when [s]."""

    value: float
    link: int
    time: float


@dataclass(frozen=True)
class RunSummary:
    """The figures a run is scored by (paper Table 2), shared by the offline run, the
    simulator node, the study and the cell runner (SI units)."""

    F_max: float            # N, largest link tension
    F_max_link: int         # which link (1 = top)
    F_max_time: float       # s, when
    SF: float               # F_break / F_max
    delta: float            # m, residual gap at the bottom

    @classmethod
    def of(cls, F_break: float, peak: PeakTension, delta: float) -> "RunSummary":
        return cls(float(peak.value), int(peak.link), float(peak.time),
                   safety_factor(F_break, peak.value), float(delta))

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def peak_tension(times: np.ndarray, tensions: np.ndarray) -> PeakTension:
    """F_max over a run: ``tensions`` is (steps, links) [N]."""
    k, i = np.unravel_index(int(np.argmax(tensions)), tensions.shape)
    return PeakTension(float(tensions[k, i]), int(i) + 1, float(times[k]))


def safety_factor(F_break: float, F_max: float) -> float:
    """SF = F_break / F_max [-] (the paper's Table 2 numbers are this ratio); inf where no
    tension is known (``F_max`` [N] NaN or <= 0), 0 for an infinite one."""
    if math.isnan(F_max) or F_max <= 0:
        return math.inf
    return float(F_break / F_max)


def residual_gap(nodes: np.ndarray, thickness: float) -> float:
    """Delta [m]: how far the sheet's inner surface stays from the wall at the bottom.

    ``nodes`` (M, 2) is the centreline polyline (bonds included).  Delta is
    the smallest x of the centreline among its points at most two thicknesses
    above the workplane, minus half a thickness (paper Fig. 12 b).  Returns
    ``inf`` when no part of the sheet is that low.
    """
    zc = 2.0 * thickness
    a, b = nodes[:-1], nodes[1:]
    best = np.inf
    lo = np.minimum(a[:, 1], b[:, 1])
    for p, q in zip(a[lo <= zc], b[lo <= zc]):
        cands = [pt[0] for pt in (p, q) if pt[1] <= zc]
        if (p[1] - zc) * (q[1] - zc) < 0.0:        # segment crosses z = zc
            s = (zc - p[1]) / (q[1] - p[1])
            cands.append(p[0] + s * (q[0] - p[0]))
        best = min(best, min(cands))
    return float(best - 0.5 * thickness)


def touching_tool(tool_force_on_masses: np.ndarray) -> np.ndarray:
    """Which masses touch the tool: a nonzero contact force of the tool on them, (..., N, 2)
    [N] -> (..., N) bool (one step or a whole run)."""
    f = np.asarray(tool_force_on_masses, dtype=float)
    return np.hypot(f[..., 0], f[..., 1]) > 0.0


def contact_tension(tension: np.ndarray, tool_force_on_masses: np.ndarray) -> float:
    """Largest tension [N] in a link touching a mass that touches the tool (0 without contact).

    ``tension`` (N+1,) link forces; ``tool_force_on_masses`` (N, 2) contact
    force of the tool on each mass.
    """
    touching = touching_tool(tool_force_on_masses)
    if not np.any(touching):
        return 0.0
    links = np.zeros(tension.shape[0], dtype=bool)
    links[:-1] |= touching      # link j ends at mass j
    links[1:] |= touching       # link j+1 starts at mass j
    return float(np.max(tension[links]))
