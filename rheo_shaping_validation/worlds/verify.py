"""How far two world runs are apart, in the sensors' units: the tool force's RMS
difference [N] and the profile's RMS distance [m] (each node of one run to the other's
centreline), on the samples both runs share.  Used by the world's convergence tests and
``benchmarks/world_convergence.py``."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamic import WorldRun


@dataclass(frozen=True)
class RunGap:
    """Differences between two runs over their common samples."""

    force_rms: float      # N, RMS over samples of |F_a - F_b| (tool force, x and z)
    force_max: float      # N, its largest sample
    profile_rms: float    # m, RMS over samples and nodes of the distance to the other profile
    profile_max: float    # m, its largest per-sample RMS
    F_max: float          # N, difference of the runs' largest link tension


def polyline_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance [m] of each of ``points`` (M, 2) to the polyline ``line`` (K, 2)."""
    a, b = line[None, :-1], line[None, 1:]
    e = b - a
    w = np.clip(((points[:, None] - a) * e).sum(-1) / (e * e).sum(-1), 0.0, 1.0)
    d = points[:, None] - a - w[..., None] * e
    return np.hypot(d[..., 0], d[..., 1]).min(axis=1)


def run_gap(a: WorldRun, b: WorldRun, profile_every: float = 0.5) -> RunGap:
    """The gap between runs ``a`` and ``b`` (same outputs times), profiles every
    ``profile_every`` [s] (the camera's 2 Hz)."""
    n = min(a.t.size, b.t.size)
    if not np.allclose(a.t[:n], b.t[:n], atol=1e-9):
        raise ValueError("the runs do not share their sample times")
    df = np.hypot(*(a.tool_force[:n] - b.tool_force[:n]).T)
    step = max(1, int(round(profile_every / float(a.t[1] - a.t[0]))))
    per = np.array([np.sqrt(np.mean(polyline_distance(a.nodes(k), b.nodes(k)) ** 2))
                    for k in range(0, n, step)])
    return RunGap(force_rms=float(np.sqrt(np.mean(df ** 2))), force_max=float(df.max()),
                  profile_rms=float(np.sqrt(np.mean(per ** 2))), profile_max=float(per.max()),
                  F_max=float(a.F_max - b.F_max))
