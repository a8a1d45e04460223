"""Crack initiation in a tensile curve: where the force stops rising.

The paper fits Eq. 5 to the tensile curve "discarding all points after the
break of material" (Sec. 3.4.3); the average break force is 1.04 N.  This
module finds that point automatically.  The rule:

1. Smooth the force of the pull (``t > 0``) with a running median over
   ``window_s`` seconds (at least 5 samples), which removes noise but keeps a
   drop.
2. A *sustained drop* starts at the first sample from which the smoothed force
   stays below its running maximum by more than
   ``tol = max(drop_fraction * running max, 4 * noise)`` for at least
   ``hold_s`` seconds (at least 3 samples); ``noise`` is a robust estimate of
   the sample-to-sample noise (median absolute first difference / 0.95).
3. Crack initiation is the maximum of the smoothed force before that drop.
   The samples up to it are kept; the others are discarded.

A curve without a sustained drop is kept whole (the test ended before the
break, or the material only plateaus: a plateau is not detected, cut such a
file by hand).  The smoothed maximum is, by construction, where the force
stopped following a rising curve; a material that softens before its crack
would bias the fit, which the residual plots show.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter


@dataclass(frozen=True)
class CrackDetection:
    """Result of :func:`detect_crack` on one curve.

    ``keep``: number of leading samples to keep (all samples of index < keep);
    ``found``: whether a sustained drop was seen; ``t_crack`` [s] and
    ``F_crack`` [N]: time and smoothed force at crack initiation (``None`` when
    not found); ``t_drop`` [s]: where the sustained drop starts.
    """

    keep: int
    found: bool
    t_crack: float | None
    F_crack: float | None
    t_drop: float | None


def detect_crack(t, F, window_s: float = 1.0, hold_s: float = 1.0,
                 drop_fraction: float = 0.03) -> CrackDetection:
    """Find crack initiation in a tensile curve ``F`` [N] at times ``t`` [s] (rule in the module
    doc)."""
    t = np.asarray(t, dtype=float)
    F = np.asarray(F, dtype=float)
    n = t.size
    pull = np.flatnonzero(t > 0.0)
    if pull.size < 8:
        return CrackDetection(n, False, None, None, None)
    i0 = int(pull[0])
    tp, Fp = t[i0:], F[i0:]
    dt = float(np.median(np.diff(tp)))
    w = max(5, int(round(window_s / dt)) | 1)
    smooth = median_filter(Fp, size=w, mode="nearest")
    # MAD of differences -> sd for Gaussian noise
    noise = float(np.median(np.abs(np.diff(Fp)))) / 0.954
    run_max = np.maximum.accumulate(smooth)
    tol = np.maximum(drop_fraction * np.abs(run_max), 4.0 * noise)
    below = smooth < run_max - tol
    hold = max(3, int(round(hold_s / dt)))
    # first index from which `below` holds for `hold` consecutive samples
    run = np.convolve(below.astype(int), np.ones(hold, dtype=int), mode="valid")
    starts = np.flatnonzero(run == hold)
    if starts.size == 0:
        return CrackDetection(n, False, None, None, None)
    j_drop = int(starts[0])
    j_peak = int(np.argmax(smooth[: j_drop + 1]))
    return CrackDetection(i0 + j_peak + 1, True, float(tp[j_peak]), float(smooth[j_peak]),
                          float(tp[j_drop]))
