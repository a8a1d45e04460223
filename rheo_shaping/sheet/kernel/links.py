"""The three-element link law of one step (paper Eq. 2-5) and the banded Cholesky solve."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .consts import JIT, P_PLN, P_PLREF, P_THIN


# --------------------------------------------------------------------- link law
@njit(**JIT)
def link_factors(k1, c1, c2, dt):
    """(r, eps, g) of material.step_factors for one unit."""
    r = 1.0 / (1.0 + c1 / c2)
    x = k1 * dt / (c1 + c2)
    if not np.isfinite(x):
        x = 0.0
    eps = math.exp(-x)
    g = 1.0 - 0.5 * x if x < 1e-8 else -math.expm1(-x) / x
    return r, eps, g


@njit(**JIT)
def link_constants(links, e1, p, tension, fpar):
    """k1, c1, c2 (N+1,) of the links over a step: thinning (L/(L+p))^b and the power-law
    c2 (F/F_ref)^(1-1/n), both lagged on the state (rheo_shaping.sheet.effects)."""
    m = links.shape[1]
    k1 = links[1].copy()
    c1 = links[2].copy()
    c2 = links[3].copy()
    b = fpar[P_THIN]
    if b > 0.0:
        for i in range(m):
            L = links[0, i]
            pp = p[i] if p[i] > 0.0 else 0.0
            s = (L / (L + pp)) ** b
            k1[i] *= s
            c1[i] *= s
            c2[i] *= s
    nexp = fpar[P_PLN]
    if nexp != 1.0:
        ref = fpar[P_PLREF]
        for i in range(m):
            F = tension[i] if tension[i] > 1e-3 * ref else 1e-3 * ref
            c2[i] *= (F / ref) ** (1.0 - 1.0 / nexp)
    return k1, c1, c2


# --------------------------------------------------------------------- band solve
@njit(**JIT)
def band_cholesky(band, kd, L):
    """Cholesky H = L L^T of a banded SPD matrix: ``band[i, k] = H[i, i+k]`` (k <= kd <= 4),
    ``L[i, k] = L[i, i-k]`` and ``L[i, 5] = 1 / L[i, i]``.  False when H is not positive
    definite."""
    m = band.shape[0]
    for j in range(m):
        s = band[j, 0]
        k0 = j - kd if j - kd > 0 else 0
        for k in range(k0, j):
            lv = L[j, j - k]
            s -= lv * lv
        if not s > 0.0:
            return False
        ljj = math.sqrt(s)
        inv = 1.0 / ljj
        L[j, 0] = ljj
        L[j, 5] = inv
        iend = j + kd + 1 if j + kd + 1 < m else m
        for i in range(j + 1, iend):
            s = band[j, i - j]
            k0 = i - kd if i - kd > 0 else 0
            for k in range(k0, j):
                s -= L[i, i - k] * L[j, j - k]
            L[i, i - j] = s * inv
    return True


@njit(**JIT)
def band_solve(L, kd, b, out):
    """``out`` = -H^-1 b from the factor of :func:`band_cholesky` (the Newton step)."""
    m = L.shape[0]
    for i in range(m):
        s = -b[i]
        k0 = i - kd if i - kd > 0 else 0
        for k in range(k0, i):
            s -= L[i, i - k] * out[k]
        out[i] = s * L[i, 5]
    for i in range(m - 1, -1, -1):
        s = out[i]
        kend = i + kd + 1 if i + kd + 1 < m else m
        for k in range(i + 1, kend):
            s -= L[k, k - i] * out[k]
        out[i] = s * L[i, 5]
