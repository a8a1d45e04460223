"""Closed-form responses of the three-element unit (paper Sec. 2 and 3.4).

Every function takes the unit's constants as a :class:`ThreeElement` (the
Maxwell model is its ``c1 = 0`` case) and numpy-broadcastable times ``t`` [s]
measured from the start of the loading (``t >= 0``).  Forces in N, elongations
in m, speeds in m/s.  Equation numbers are the paper's.

At a step of the input (the start of a pull, a force put on or taken off) the
functions return the value just after the step (right limit): ``tensile_force``
at ``t = 0`` is Eq. 11, ``creep_elongation`` at ``t = 0`` is ``F/k1`` for a
Maxwell unit.
"""
from __future__ import annotations

import numpy as np

from ..params.validators import check_non_negative, check_positive
from .three_element import ThreeElement


def _times(t) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    if np.isnan(t).any() or (t < 0.0).any():
        bad = t[np.isnan(t) | (t < 0.0)].flat[0]
        raise ValueError(
            f"time t [s] = {float(bad)!r}: expected t >= 0 (from the start of the loading)")
    return t


def _decay(rate_num: float, rate_den: float, t: np.ndarray) -> np.ndarray:
    """``exp(-rate_num/rate_den * t)``; ``rate_den = 0`` is an instant decay (0 for t >= 0)."""
    if rate_den == 0.0:
        return np.zeros_like(t)
    return np.exp(-(rate_num / rate_den) * t)


def _rise(rate_num: float, rate_den: float, t: np.ndarray) -> np.ndarray:
    """``1 - exp(-rate_num/rate_den * t)`` without cancellation; ``rate_den = 0``: 1."""
    if rate_den == 0.0:
        return np.ones_like(t)
    return -np.expm1(-(rate_num / rate_den) * t)


def kv_elongation(m: ThreeElement, t, speed: float) -> np.ndarray:
    """Eq. 3: Kelvin-Voigt elongation x1(t) [m] during a pull at constant ``speed``.

    ``x1 = c2 v/k1 * (1 - exp(-k1 t/(c1+c2)))``.
    """
    v = check_positive("speed [m/s]", speed)
    t = _times(t)
    if np.isinf(m.c2):               # no plastic flow: the KV element takes it all
        return v * t
    return m.c2 * v / m.k1 * -np.expm1(-m.k1 * t / (m.c1 + m.c2))


def kv_rate(m: ThreeElement, t, speed: float) -> np.ndarray:
    """Eq. 4: rate dx1/dt [m/s] = c2 v/(c1+c2) * exp(-k1 t/(c1+c2))."""
    v = check_positive("speed [m/s]", speed)
    t = _times(t)
    if np.isinf(m.c2):
        return np.full_like(t, v)
    return m.c2 * v / (m.c1 + m.c2) * np.exp(-m.k1 * t / (m.c1 + m.c2))


def tensile_force(m: ThreeElement, t, speed: float) -> np.ndarray:
    """Eq. 5: force F(t) [N] of a pull at constant ``speed`` [m/s] from rest at t = 0.

    ``F = c2 v (1 - c2/(c1+c2) * exp(-k1 t/(c1+c2)))``; at t = 0 this is Eq. 11.
    """
    v = check_positive("speed [m/s]", speed)
    t = _times(t)
    if np.isinf(m.c2):               # Kelvin-Voigt solid: F = k1 v t + c1 v
        return m.k1 * v * t + m.c1 * v
    r = m.c2 / (m.c1 + m.c2)
    # 1 - r e^-x written as (1 - r) - r expm1(-x): no cancellation at small t
    return m.c2 * v * (m.c1 / (m.c1 + m.c2) - r * np.expm1(-m.k1 * t / (m.c1 + m.c2)))


def asymptotic_tensile_force(m: ThreeElement, speed: float) -> float:
    """Eq. 6: F_max = c2 v [N], the force a long pull tends to."""
    return m.c2 * check_positive("speed [m/s]", speed)


def initial_force(m: ThreeElement, speed: float) -> float:
    """Eq. 11: F(t = 0) = c2 v (1 - c2/(c1+c2)) [N]; zero for a Maxwell unit."""
    v = check_positive("speed [m/s]", speed)
    if np.isinf(m.c2):
        return m.c1 * v
    return m.c2 * v * (1.0 - m.c2 / (m.c1 + m.c2))


def creep_elongation(m: ThreeElement, t, force: float) -> np.ndarray:
    """Eq. 7-8: elongation x2(t) [m] under a constant ``force`` [N] put on at t = 0.

    ``x2 = F t/c2 + F/k1 (1 - exp(-k1 t/c1))``: the plastic part x2,1 (Eq. 8,
    first line) plus the recoverable Kelvin-Voigt part x2,2 (Eq. 8, second
    line), which is ``F/k1`` at once when ``c1 = 0``.
    """
    F = check_non_negative("force [N]", force)
    t = _times(t)
    plastic = F * t / m.c2
    recoverable = F / m.k1 * _rise(m.k1, m.c1, t)
    return plastic + recoverable


def creep_recovery(m: ThreeElement, t, force: float, t1: float) -> np.ndarray:
    """Creep then recovery: ``force`` [N] on from t = 0 to ``t1`` [s], then off.

    For ``t < t1`` this is Eq. 7-8.  After unloading the recoverable part
    decays, ``x2(t) = F t1/c2 + F/k1 (1 - exp(-k1 t1/c1)) exp(-k1 (t-t1)/c1)``,
    towards the residual ``F t1/c2`` of Eq. 9 (reached at once when c1 = 0).
    """
    F = check_non_negative("force [N]", force)
    t1 = check_positive("t1 [s]", t1)
    t = _times(t)
    loading = creep_elongation(m, np.minimum(t, t1), F)
    kv_at_t1 = F / m.k1 * _rise(m.k1, m.c1, np.asarray(t1, dtype=float))
    unloaded = F * t1 / m.c2 + kv_at_t1 * _decay(m.k1, m.c1, np.maximum(t - t1, 0.0))
    return np.where(t < t1, loading, unloaded)


def creep_residual(m: ThreeElement, force: float, t1: float) -> float:
    """Eq. 9: non-recoverable elongation x2(t -> inf) = F t1/c2 [m] after a creep test."""
    return check_non_negative("force [N]", force) * check_positive("t1 [s]", t1) / m.c2


def c2_from_creep_residual(force: float, t1: float, residual: float) -> float:
    """Eq. 10: c2 = F t1 / x2(t -> inf) [N s/m]."""
    F = check_positive("force [N]", force)
    t1 = check_positive("t1 [s]", t1)
    return F * t1 / check_positive("residual elongation [m]", residual)


def c1_from_initial_force(F0: float, c2: float, speed: float) -> float:
    """Eq. 11 solved for c1: c1 = c2 F0/(c2 v - F0) [N s/m] (0 when F0 <= 0).

    Needs ``F0 < c2 v``; a larger ``F0`` has no three-element explanation and
    raises :class:`ValueError`.
    """
    c2 = check_positive("c2 [N s/m]", c2)
    v = check_positive("speed [m/s]", speed)
    if not np.isfinite(F0):
        raise ValueError(f"initial force F0 [N] = {F0!r}: expected a finite number")
    if F0 <= 0.0:
        return 0.0
    if F0 >= c2 * v:
        raise ValueError(
            f"initial force F0 [N] = {F0!r}: expected F0 < c2 v = {c2 * v!r} N (Eq. 11)")
    return c2 * F0 / (c2 * v - F0)


def linearised_tensile(t, F, c1: float, c2: float, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 12-13: ``(X, Y)`` with ``Y + b X = 0`` and ``b = k1/(c1+c2)`` [1/s].

    ``X = t``, ``Y = ln(1 - F/(c2 v)) + ln((c1+c2)/c2)``.  Points with
    ``F >= c2 v`` (no logarithm) give ``Y = nan``; the caller drops them.
    """
    c2 = check_positive("c2 [N s/m]", c2)
    c1 = check_non_negative("c1 [N s/m]", c1)
    v = check_positive("speed [m/s]", speed)
    t = np.asarray(t, dtype=float)
    u = 1.0 - np.asarray(F, dtype=float) / (c2 * v)
    with np.errstate(invalid="ignore", divide="ignore"):
        Y = np.where(u > 0.0, np.log(np.where(u > 0.0, u, 1.0)), np.nan) + np.log((c1 + c2) / c2)
    return t, Y
