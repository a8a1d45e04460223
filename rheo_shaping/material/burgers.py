"""Burgers (four-element) model: an extension beyond the paper.

A Maxwell element (spring ``k2`` [N/m] in series with dashpot ``c2`` [N s/m])
in series with a Kelvin-Voigt element (spring ``k1`` [N/m] parallel to dashpot
``c1`` [N s/m]).  The paper's three-element unit is its ``k2 = inf`` case and
the Maxwell model the ``k2 = inf, c1 = 0`` case, so the three models are
nested (:mod:`rheo_shaping.identification.model_choice` compares them).

State of a unit: force ``F`` (the spring k2 stretches ``F/k2``), Kelvin-Voigt
elongation ``e1`` and plastic elongation ``p`` of c2 [m]; its elongation is
``x = F/k2 + e1 + p``.  With ``j2 = 1/k2`` the ODEs are

    dF/dt = k2 (dx/dt - (F - k1 e1)/c1 - F/c2),     de1/dt = (F - k1 e1)/c1,

and the constitutive law ``F + p1 F' + p2 F'' = c2 x' + (c1 c2/k1) x''`` with
``p1 = c2 j2 + (c1 + c2)/k1`` and ``p2 = c1 c2 j2/k1``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from .closed_forms import _times

from ..params.validators import check_non_negative, check_positive, check_time_step
from .three_element import SPECIMEN_LENGTH_M, ThreeElement, elongation_step


@dataclass(frozen=True)
class Burgers:
    """Constants of a Burgers unit of rest length ``length`` [m].

    ``k1`` [N/m], ``c1`` [N s/m] (Kelvin-Voigt), ``c2`` [N s/m], ``k2`` [N/m]
    (Maxwell); ``k2 = inf`` is the three-element unit.
    """

    k1: float
    c1: float
    c2: float
    k2: float
    length: float = SPECIMEN_LENGTH_M

    def __post_init__(self) -> None:
        check_positive("k1 [N/m]", self.k1)
        check_non_negative("c1 [N s/m]", self.c1)
        check_positive("c2 [N s/m]", self.c2)
        check_positive("k2 [N/m]", self.k2, allow_inf=True)
        check_positive("length [m]", self.length)

    @property
    def j2(self) -> float:
        """Compliance 1/k2 [m/N] of the series spring (0 for the three-element unit)."""
        return 0.0 if math.isinf(self.k2) else 1.0 / self.k2

    def scaled(self, length: float) -> "Burgers":
        """The same material over another rest length [m] (every constant times L0/l)."""
        check_positive("length [m]", length)
        s = self.length / length
        return Burgers(self.k1 * s, self.c1 * s, self.c2 * s, self.k2 * s, length)

    def three_element(self) -> ThreeElement:
        """The three-element unit (k1, c1, c2), exact when ``k2 = inf``."""
        return ThreeElement(self.k1, self.c1, self.c2, self.length)


def as_burgers(m: "ThreeElement | Burgers") -> Burgers:
    """A three-element unit as the ``k2 = inf`` Burgers unit (Burgers units pass through)."""
    if isinstance(m, Burgers):
        return m
    if math.isinf(m.c2):
        raise ValueError("c2 [N s/m] = inf: a Burgers unit needs a finite series dashpot")
    return Burgers(m.k1, m.c1, m.c2, math.inf, m.length)


def _kv_creep(b: Burgers, t: np.ndarray, force: float) -> np.ndarray:
    if b.c1 == 0.0:
        return np.full_like(t, force / b.k1)
    return force / b.k1 * -np.expm1(-b.k1 * t / b.c1)


def burgers_creep(b: Burgers, t, force: float) -> np.ndarray:
    """Elongation [m] under a constant ``force`` [N] put on at t = 0 (right limit at 0).

    ``x = F/k2 + F t/c2 + F/k1 (1 - exp(-k1 t/c1))`` (Eq. 7-8 plus the
    instantaneous stretch of k2).
    """
    F = check_non_negative("force [N]", force)
    t = _times(t)
    return F * b.j2 + F * t / b.c2 + _kv_creep(b, t, F)


def burgers_creep_recovery(b: Burgers, t, force: float, t1: float) -> np.ndarray:
    """``force`` [N] on from 0 to ``t1`` [s], then off: elongation [m].

    After unloading k2 recovers at once and the Kelvin-Voigt part decays
    towards the residual ``F t1/c2`` (Eq. 9-10 hold unchanged).
    """
    F = check_non_negative("force [N]", force)
    t1 = check_positive("t1 [s]", t1)
    t = _times(t)
    loading = burgers_creep(b, np.minimum(t, t1), F)
    kv1 = _kv_creep(b, np.asarray(t1, dtype=float), F)
    after = np.maximum(t - t1, 0.0)
    decay = np.zeros_like(after) if b.c1 == 0.0 else np.exp(-b.k1 * after / b.c1)
    unloaded = F * t1 / b.c2 + kv1 * decay
    return np.where(t < t1, loading, unloaded)


def burgers_tensile_force(b: Burgers, t, speed: float) -> np.ndarray:
    """Force [N] of a pull at constant ``speed`` [m/s] from rest at t = 0.

    ``F = c2 v + A_f exp(s_f t) + A_s exp(s_s t)`` where ``s_f, s_s`` are the
    roots of ``p2 s^2 + p1 s + 1 = 0`` and ``F(0) = 0``, ``F'(0) = k2 v``.
    The roots are real and distinct.  ``k2 = inf`` gives Eq. 5 (with its jump
    Eq. 11 at t = 0+), ``c1 = 0`` a Maxwell unit of stiffness k1 k2/(k1+k2).
    """
    v = check_positive("speed [m/s]", speed)
    t = _times(t)
    k1, c1, c2, j2 = b.k1, b.c1, b.c2, b.j2
    p1 = c2 * j2 + (c1 + c2) / k1
    p2 = c1 * c2 * j2 / k1
    if p2 == 0.0:
        # single exponential exp(-t/p1); A_s from the p2 -> 0 limit
        A_s = v * c2 * (c1 / k1 - p1) / p1
        return (c2 * v + A_s) + A_s * np.expm1(-t / p1)
    q = -0.5 * (p1 + math.sqrt(p1 * p1 - 4.0 * p2))   # stable roots
    s_fast, s_slow = q / p2, 1.0 / q
    A_s = v * q * c2 * (c1 / k1 + q) / (p2 - q * q)
    A_f = -c2 * v - A_s
    # c2 v + A_f e^(s_f t) + A_s e^(s_s t) with c2 v + A_f + A_s = 0, without cancellation
    return A_f * np.expm1(s_fast * t) + A_s * np.expm1(s_slow * t)


def _taut_propagator(b: Burgers, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact step of y = (F, e1) over ``dt`` at constant dx/dt = v: y' = Phi y + Gamma v."""
    k1, c1, c2, k2 = b.k1, b.c1, b.c2, b.k2
    M = np.zeros((3, 3))
    M[0, 0] = -k2 * (1.0 / c1 + 1.0 / c2)
    M[0, 1] = k2 * k1 / c1
    M[1, 0] = 1.0 / c1
    M[1, 1] = -k1 / c1
    M[0, 2] = k2
    E = expm(M * dt)      # Van Loan: [[Phi, Gamma], [0, 1]]
    return E[:2, :2], E[:2, 2]


def burgers_elongation_step(b: Burgers, F: float, e1: float, p: float, delta: float,
                            dt: float, _cache: dict | None = None) -> tuple[float, float, float]:
    """Advance a Burgers unit whose length grows linearly by ``delta`` [m] over ``dt`` [s].

    ``delta`` is the length at the end minus the free length ``L0 + F/k2 + e1
    + p`` at the start.  Exact (matrix exponential) while the unit stays taut;
    like :func:`rheo_shaping.material.three_element.elongation_step`, a unit whose end force
    would be negative is slack: no force, k2 unstretched, c2 still, and the
    Kelvin-Voigt part relaxes freely.  ``k2 = inf`` and ``c1 = 0`` reuse that
    three-element step.  Returns ``(F [N], e1 [m], p [m])``.
    """
    check_time_step(dt)
    if math.isinf(b.k2):
        Fn, e1n, pn = elongation_step(b.k1, b.c1, b.c2, e1, p, delta, dt)
        return float(Fn), float(e1n), float(pn)
    if b.c1 == 0.0:
        # springs k1 and k2 in series: a Maxwell unit of stiffness k
        k = b.k1 * b.k2 / (b.k1 + b.k2)
        Fn, _, pn = elongation_step(k, 0.0, b.c2, F / k, p, delta, dt)
        Fn = float(Fn)
        return Fn, Fn / b.k1, float(pn)
    key = float(dt)
    if _cache is not None and key in _cache:
        Phi, Gamma = _cache[key]
    else:
        Phi, Gamma = _taut_propagator(b, dt)
        if _cache is not None:
            _cache[key] = (Phi, Gamma)
    y = Phi @ np.array([F, e1]) + Gamma * (delta / dt)
    Fn, e1n = float(y[0]), float(y[1])
    if Fn > 0.0:
        pn = p + delta - (Fn - F) / b.k2 - (e1n - e1)
        return Fn, e1n, pn
    return 0.0, e1 * math.exp(-b.k1 * dt / b.c1), p
