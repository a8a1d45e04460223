"""The gap watch's residual figures: sums of squared residuals and what they say in noise
units, the robust noise estimate, the signed distance of camera points to the model's
centreline, and the watch's status (:mod:`.watch`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class _Sums:
    """Sum of squared residuals and their count (one observable, one group)."""

    n: int = 0
    r2: float = 0.0

    def add(self, r2: float, n: int) -> None:
        self.n += n
        self.r2 += r2

    def figures(self, noise: float) -> dict:
        """rms, systematic part, RMS in noise units (None without data)."""
        if self.n == 0:
            return {"rms": None, "systematic": None, "z": None, "n": 0}
        ms = self.r2 / self.n
        return {"rms": math.sqrt(ms), "systematic": math.sqrt(max(ms - noise * noise, 0.0)),
                "z": math.sqrt(ms) / noise, "n": self.n}


@dataclass
class Status:
    """What the watch says now (everything a node publishes)."""

    level: str                     # STALE, OK, WARN, ERROR, FAILED
    message: str
    process_time: float            # s, newest judged time
    model_time: float              # s, the model's time
    residuals: dict                # see GapWatch.residuals
    first_warn: float | None       # s, process time of the first WARN of the run
    first_error: float | None


def mad_sigma(second_differences) -> float:
    """Std of white noise from its second differences x[i-1] - 2 x[i] + x[i+1] (std s sqrt 6),
    robustly (MAD), as :func:`rheo_shaping.diagnosis.compare.noise_level`; 0 with fewer than 5."""
    d = np.asarray(second_differences, float)
    if d.size < 5:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(6.0))


def signed_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Signed normal distance [m] of ``points`` (P, 2) to the polyline ``line`` (K, 2): positive
    on the side of its left normal (away from the mould for a sheet from the cake top down), as
    :func:`rheo_shaping.diagnosis.compare.residuals` measures it."""
    a = line[:-1]
    seg = line[1:] - a
    L2 = np.einsum("sk,sk->s", seg, seg)
    rel = points[:, None, :] - a[None]
    s = np.clip(np.einsum("psk,sk->ps", rel, seg) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    foot = a[None] + s[..., None] * seg[None]
    diff = points[:, None, :] - foot
    d2 = np.einsum("psk,psk->ps", diff, diff)
    j = np.argmin(d2, axis=1)
    idx = np.arange(len(j))
    cross = seg[j, 0] * diff[idx, j, 1] - seg[j, 1] * diff[idx, j, 0]
    return np.sqrt(d2[idx, j]) * np.sign(cross)
