"""Reference solutions that verify the sheet simulator (independent of it).

* :func:`elastic_chain_equilibrium`: exact static equilibrium of N point
  masses joined by N + 1 linear elastic, tension-only links between two fixed
  anchors under gravity (-z), by shooting on the anchor reaction.
* :func:`rheo_shaping.sheet.catenary.irvine_catenary`: Irvine's elastic catenary
  (H. M. Irvine, *Cable Structures*, MIT Press 1981, Sec. 2.2), the continuous
  cable the chain converges to.
* :func:`rheo_shaping.sheet.catenary.discretise_cable`: the lumped-mass chain that
  approximates a given elastic cable (what the simulator does with the sheet).

Conventions (frame ``cake``): z up, gravity ``-g ez``.  Anchor A is the start
of the chain / cable (Lagrangian coordinate s = 0).  ``H`` [N] is the
horizontal component of the tension (constant along the chain, positive when
B lies at larger x than A) and ``V`` [N] the *upward* force the support A
exerts on the chain.  The tension vector of link i, pointing from A's side to
B's side, is then

    T_i = (H, g * sum_{j < i} m_j - V),

i.e. the brief's ``(H, V - g * sum m)`` with the vertical sign flipped so that
``V`` is the support's upward reaction (the chain descends from A while
``V > g * sum m``).  Link i is ``L_i + |T_i| / k_i`` long and lies along
``T_i / |T_i|``.

Convergence of the lumped chain to Irvine's cable (``discretise_cable``,
``benchmarks/catenary_convergence.py``): the largest node error decreases as
1/N^2 (ratios ~4.0 per halving of the link length, ~6.25 from N = 20 to 50).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..params.validators import PointLike, check_finite

__all__ = [
    "ChainEquilibrium",
    "solve_elastic_chain",
    "elastic_chain_equilibrium",
    "initial_reactions",
]


# --------------------------------------------------------------------- helpers


def initial_reactions(dx: float, dz: float, total_rest_length: float, total_weight: float,
                      series_stiffness: float) -> tuple[float, float]:
    """Guess (H, V) [N]: parabolic sag for a slack chain, straight stretch for a taut one."""
    chord = math.hypot(dx, dz)
    span = abs(dx)
    h_sag = 0.0
    if total_rest_length > chord:
        sag = math.sqrt(3.0 * chord * (total_rest_length - chord) / 8.0)
        h_sag = total_weight * max(span, 1e-3 * chord) / (8.0 * sag)
    h_str = series_stiffness * max(chord - total_rest_length, 0.0) * span / chord
    h = max(h_sag, h_str, 1e-3 * total_weight, 1e-12)
    h = math.copysign(h, dx if dx != 0.0 else 1.0)
    v = 0.5 * total_weight - (h * dz / dx if dx != 0.0 else 0.0)
    return h, v


# ----------------------------------------------------------------- lumped chain


@dataclass(frozen=True)
class ChainEquilibrium:
    """Static equilibrium of a lumped elastic chain.

    ``positions`` (N, 2) [m]; ``tensions`` (N+1,) [N] and ``lengths`` (N+1,)
    [m] per link; ``H`` [N] horizontal tension, ``V`` [N] upward reaction at A;
    ``mismatch`` [m] the end-point error of the shooting; ``iterations``.
    """

    positions: np.ndarray
    tensions: np.ndarray
    lengths: np.ndarray
    H: float
    V: float
    mismatch: float
    iterations: int


def _chain_walk(hv: np.ndarray, a: np.ndarray, rest: np.ndarray, inv_k: np.ndarray,
                w_before: np.ndarray, jac: bool) -> tuple:
    """Walk from A link by link for reactions ``hv = (H, V)``: segment vectors
    (N+1, 2), tensions (N+1,), end point (2,) and d(end)/d(H, V) (2, 2)."""
    tx = np.full_like(rest, hv[0])
    tz = w_before - hv[1]
    t = np.hypot(tx, tz)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = rest / t + inv_k                   # (L + T/k) / T
    seg = np.column_stack((scale * tx, scale * tz))
    end = a + seg.sum(axis=0)
    if not jac:
        return seg, t, end, None
    # d seg / dT = (L/T) (I - u u^T) + I/k;   dT/dH = (1, 0), dT/dV = (0, -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ux, uz = tx / t, tz / t
        lt = rest / t
    j = np.empty((2, 2))
    j[0, 0] = np.sum(lt * (1.0 - ux * ux) + inv_k)
    j[1, 0] = np.sum(-lt * uz * ux)
    j[0, 1] = -np.sum(-lt * ux * uz)
    j[1, 1] = -np.sum(lt * (1.0 - uz * uz) + inv_k)
    return seg, t, end, j


def solve_elastic_chain(anchor_a: PointLike, anchor_b: PointLike, rest_lengths: ArrayLike,
                        stiffness: ArrayLike, masses: ArrayLike, g: float = 9.81,
                        tol: float = 1e-15, max_iter: int = 200) -> ChainEquilibrium:
    """Exact equilibrium of N masses ``masses`` (N,) [kg] joined by N + 1 links
    of rest length ``rest_lengths`` (N+1,) [m] and stiffness ``stiffness``
    (N+1,) [N/m] (force k (l - L), all taut) between anchors A and B [m].

    Shooting on (H, V) with a damped Newton iteration (analytic Jacobian)
    until the chain's far end is within ``tol`` [m] of B (must reach 1e-12 m).
    Raises ValueError for bad input or a link that would be slack (zero
    tension), RuntimeError when the iteration fails.
    """
    a = np.asarray(anchor_a, dtype=float).reshape(-1)
    b = np.asarray(anchor_b, dtype=float).reshape(-1)
    rest = np.asarray(rest_lengths, dtype=float).reshape(-1)
    k = np.asarray(stiffness, dtype=float).reshape(-1)
    m = np.asarray(masses, dtype=float).reshape(-1)
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise ValueError(f"anchor_a: {anchor_a!r}, expected finite (x, z) [m]")
    if b.shape != (2,) or not np.all(np.isfinite(b)):
        raise ValueError(f"anchor_b: {anchor_b!r}, expected finite (x, z) [m]")
    n = m.size
    if rest.size != n + 1:
        raise ValueError(
            f"rest_lengths: {rest.size} values, expected N + 1 = {n + 1} (N = {n} masses)")
    if k.size != n + 1:
        raise ValueError(f"stiffness: {k.size} values, expected N + 1 = {n + 1} (N = {n} masses)")
    if not np.all(np.isfinite(rest)) or np.any(rest <= 0.0):
        raise ValueError(f"rest_lengths [m]: min {rest.min()!r}, expected finite values > 0")
    if not np.all(np.isfinite(k)) or np.any(k <= 0.0):
        raise ValueError(f"stiffness [N/m]: min {k.min()!r}, expected finite values > 0")
    if n and (not np.all(np.isfinite(m)) or np.any(m < 0.0)):
        raise ValueError(f"masses [kg]: min {m.min()!r}, expected finite values >= 0")
    g = check_finite("g [m/s^2]", g)
    if g < 0.0:
        raise ValueError(f"g [m/s^2]: {g!r}, expected >= 0")

    inv_k = 1.0 / k
    chord = float(np.hypot(*(b - a)))
    if g * float(m.sum()) == 0.0 and float(rest.sum()) >= chord:
        raise ValueError(f"weightless chain of rest length {float(rest.sum())!r} m between "
                         f"anchors {chord!r} m "
                         "apart: every link would be slack (tension-only links need rest length < "
                         "chord)")
    w_before = g * np.concatenate(([0.0], np.cumsum(m)))       # weight hung before link i [N]
    total_w = float(w_before[-1])
    dx, dz = (b - a).tolist()
    hv = np.array(initial_reactions(dx, dz, float(rest.sum()), total_w, 1.0 / float(inv_k.sum())))

    scale_len = max(float(rest.sum()), math.hypot(dx, dz))
    seg, t, end, j = _chain_walk(hv, a, rest, inv_k, w_before, True)
    res = end - b
    err = float(np.hypot(*res))
    it = 0
    stalled = 0
    while it < max_iter and err > tol:
        it += 1
        try:
            step = -np.linalg.solve(j, res)
        except np.linalg.LinAlgError as exc:
            raise RuntimeError(
                f"elastic chain: singular Jacobian at H = {hv[0]!r} N, V = {hv[1]!r} N") from exc
        alpha = 1.0
        while True:
            trial = hv + alpha * step
            seg_t, t_t, end_t, j_t = _chain_walk(trial, a, rest, inv_k, w_before, True)
            err_t = float(np.hypot(*(end_t - b)))
            if np.isfinite(err_t) and (err_t < err * (1.0 - 1e-4 * alpha) or err_t <= tol):
                break
            alpha *= 0.5
            if alpha < 1e-12:
                break
        if not (np.isfinite(err_t) and err_t < err):
            stalled += 1                          # round-off floor: no further progress possible
            if stalled >= 2 or alpha < 1e-12:
                break
            continue
        hv, seg, t, end, j, err = trial, seg_t, t_t, end_t, j_t, err_t
        res = end - b
    if not err <= max(1e-12, 1e-14 * scale_len):
        raise RuntimeError(f"elastic chain: end-point mismatch {err:.3e} m after {it} iterations, "
                           f"expected <= 1e-12 m (H = {hv[0]:.6g} N, V = {hv[1]:.6g} N)")
    t_min = float(t.min())
    if not t_min > 1e-9 * max(total_w, abs(float(hv[0])), 1e-300):
        i = int(np.argmin(t))
        raise ValueError(f"link {i} would be slack (tension {t_min:.3e} N): a tension-only link "
                         "cannot "
                         "carry this configuration")
    pos = a + np.cumsum(seg, axis=0)[:n]
    return ChainEquilibrium(positions=pos, tensions=t, lengths=rest + t * inv_k, H=float(hv[0]),
                            V=float(hv[1]), mismatch=err, iterations=it)


def elastic_chain_equilibrium(anchor_a: PointLike, anchor_b: PointLike,
                              rest_lengths: ArrayLike, stiffness: ArrayLike,
                              masses: ArrayLike, g: float = 9.81) -> np.ndarray:
    """Positions (N, 2) [m] of the masses at static equilibrium; see
    :func:`solve_elastic_chain` for the arguments and the tensions."""
    return solve_elastic_chain(anchor_a, anchor_b, rest_lengths, stiffness, masses, g).positions
