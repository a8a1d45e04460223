"""The world's link law (paper Eq. 2, backward Euler over a step, see the package
docstring) and its banded SPD solve."""
from __future__ import annotations

import math

from numba import njit

from .consts import I_HARD, I_PL_N, I_PL_REF, I_THIN, JIT


# ---------------------------------------------------------------- links (paper Eq. 2)
@njit(**JIT)
def link_affine(k1, c1, c2, e1, h):
    """(A, S): the backward-Euler link force F' = A + S D [N] over a step ``h`` [s], D [m] the
    end length beyond the free length L0 + e1 + p (Eq. 2 discretised)."""
    den = c1 + c2 + k1 * h
    g = k1 + c1 / h
    S = g * c2 / den
    A = g * (c1 + c2) * e1 / den - c1 / h * e1
    return A, S


@njit(**JIT)
def link_update(k1, c1, c2, e1, p, D, h):
    """(e1', p', F') of one link after a step ``h`` whose end length is D beyond the free
    length; slack (F' < 0): no force, no flow, the Kelvin part relaxes."""
    den = c1 + c2 + k1 * h
    e1n = ((c1 + c2) * e1 + c2 * D) / den
    F = k1 * e1n + c1 * (e1n - e1) / h
    if F >= 0.0:
        return e1n, p + D - (e1n - e1), F
    return c1 * e1 / (c1 + k1 * h), p, 0.0


@njit(**JIT)
def link_constants(L0, k1, c1, c2, e1, p, tension, par, out):
    """k1, c1, c2 of every link over this step, lagged on the state: thinning (L0/(L0+p))^b,
    power-law c2 (F/F_ref)^(1-1/n), strain hardening k1 (1 + beta (l - L0)/L0)."""
    b = par[I_THIN]
    n = par[I_PL_N]
    ref = par[I_PL_REF]
    beta = par[I_HARD]
    for i in range(L0.size):
        s = 1.0
        if b > 0.0 and p[i] > 0.0:
            s = (L0[i] / (L0[i] + p[i])) ** b
        kk = k1[i] * s
        if beta != 0.0:
            strain = (e1[i] + p[i]) / L0[i]
            kk *= 1.0 + beta * max(strain, 0.0)
        cc2 = c2[i] * s
        if n != 1.0:
            F = max(tension[i], 1e-3 * ref)
            cc2 *= (F / ref) ** (1.0 - 1.0 / n)
        out[0, i] = kk
        out[1, i] = c1[i] * s
        out[2, i] = cc2


# ---------------------------------------------------------------- banded SPD solve
@njit(**JIT)
def pb_factor(ab, kd):
    """In-place Cholesky of an SPD band matrix in LAPACK lower storage ``ab[d, j] = A[j + d,
    j]`` (d <= kd); False when not positive definite."""
    n = ab.shape[1]
    for j in range(n):
        lo = max(0, j - kd)
        acc = ab[0, j]
        for k in range(lo, j):
            acc -= ab[j - k, k] ** 2
        if acc <= 0.0:
            return False
        djj = math.sqrt(acc)
        ab[0, j] = djj
        for i in range(j + 1, min(n, j + kd + 1)):
            acc = ab[i - j, j]
            for k in range(max(0, i - kd), j):
                acc -= ab[i - k, k] * ab[j - k, k]
            ab[i - j, j] = acc / djj
    return True


@njit(**JIT)
def pb_solve(ab, kd, rhs):
    """Solve with the factor of :func:`pb_factor`, ``rhs`` overwritten by the solution."""
    n = ab.shape[1]
    for j in range(n):
        acc = rhs[j]
        for k in range(max(0, j - kd), j):
            acc -= ab[j - k, k] * rhs[k]
        rhs[j] = acc / ab[0, j]
    for j in range(n - 1, -1, -1):
        acc = rhs[j]
        for i in range(j + 1, min(n, j + kd + 1)):
            acc -= ab[i - j, j] * rhs[i]
        rhs[j] = acc / ab[0, j]


@njit(**JIT)
def add_block(ab, a, b, kxx, kxz, kzz):
    """Add the symmetric 2x2 block [[kxx, kxz], [kxz, kzz]] at masses (a, b) (a >= b) of the
    band; a negative index (a bond) adds nothing."""
    if a < 0 or b < 0:
        return
    ra = 2 * a
    rb = 2 * b
    if a == b:
        ab[0, ra] += kxx
        ab[1, ra] += kxz
        ab[0, ra + 1] += kzz
    else:
        ab[ra - rb, rb] += kxx
        ab[ra - rb + 1, rb] += kxz          # row ra+1 (z of a), column rb (x of b)
        ab[ra - rb - 1, rb + 1] += kxz      # row ra (x of a), column rb+1 (z of b)
        ab[ra - rb, rb + 1] += kzz
