"""Closed-form references for a hanging cable (verification of the sheet model):
Irvine's elastic catenary, the inextensible catenary, and the lumped chain a cable
becomes when it is cut into N masses (:func:`discretise_cable`).  The elastic chain of
lumped masses itself is :mod:`rheo_shaping.sheet.analytic`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq, root

from ..params.validators import check_finite
from .analytic import ChainEquilibrium, initial_reactions, solve_elastic_chain


# ------------------------------------------------------------ Irvine's catenary


@dataclass(frozen=True)
class IrvineCable:
    """An elastic catenary solved for its support reactions.

    Supports (0, 0) and (``span``, ``height_difference``) [m]; unstretched
    length ``L0`` [m]; axial stiffness ``EA`` [N]; weight per unstretched
    length ``w`` [N/m]; ``H`` [N] horizontal tension, ``V`` [N] upward
    reaction at (0, 0).
    """

    span: float
    height_difference: float
    L0: float
    EA: float
    w: float
    H: float
    V: float

    def position(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(x, z) [m] of the material point at Lagrangian coordinate s [m]."""
        return _irvine_xz(np.asarray(s, dtype=float), self.H, self.V, self.EA, self.w)

    def tension(self, s: ArrayLike) -> np.ndarray:
        """Tension [N] at Lagrangian coordinate s [m]."""
        return np.hypot(self.H, self.w * np.asarray(s, dtype=float) - self.V)


def _asinh_sum(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """asinh(a) + asinh(b) without cancellation when a ~ -b."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    same = a * b >= 0.0
    ra, rb = np.sqrt(1.0 + a * a), np.sqrt(1.0 + b * b)
    den = a * rb - b * ra                               # no cancellation where a, b differ in sign
    with np.errstate(divide="ignore", invalid="ignore"):
        mixed = np.arcsinh((a + b) * (a - b) / den)
    return np.where(same, np.arcsinh(a) + np.arcsinh(b), np.where(den != 0.0, mixed, 0.0))


def _irvine_xz(s: np.ndarray, h: float, v: float, ea: float,
               w: float) -> tuple[np.ndarray, np.ndarray]:
    """Irvine's closed form with z up, s from support A (H > 0)."""
    ta = math.hypot(h, v)
    ts = np.hypot(h, w * s - v)
    x = h * s / ea + (h / w) * _asinh_sum((w * s - v) / h, v / h)
    # (1/w)(T(s) - T(0)) = s (w s - 2 V) / (T(s) + T(0)), free of cancellation
    z = (0.5 * w * s * s - v * s) / ea + s * (w * s - 2.0 * v) / (ts + ta)
    return x, z


def _irvine_residual(hv: np.ndarray, span: float, hd: float, l0: float, ea: float,
                     w: float) -> tuple:
    h, v = float(hv[0]), float(hv[1])
    if not h > 0.0:
        return np.array([np.nan, np.nan]), np.full((2, 2), np.nan)
    x, z = _irvine_xz(np.array(l0), h, v, ea, w)
    ta, tb = math.hypot(h, v), math.hypot(h, w * l0 - v)
    j = np.empty((2, 2))
    j[0, 0] = l0 / ea + float(_asinh_sum((w * l0 - v) / h, v / h)) / \
        w - ((w * l0 - v) / tb + v / ta) / w
    j[0, 1] = (h / w) * (1.0 / ta - 1.0 / tb)
    j[1, 0] = (h / w) * (1.0 / tb - 1.0 / ta)
    j[1, 1] = -l0 / ea - ((w * l0 - v) / tb + v / ta) / w
    return np.array([float(x) - span, float(z) - hd]), j


def solve_irvine(span: float, height_difference: float, unstretched_length: float, EA: float,
                 weight_per_length: float) -> IrvineCable:
    """Solve Irvine's two compatibility equations x(L0) = span, z(L0) =
    height_difference for the support reactions (scipy ``root``, then Newton
    polishing to round-off).  ``span`` > 0 [m] (the vertical cable is excluded)."""
    span = check_finite("span [m]", span, positive=True)
    hd = check_finite("height_difference [m]", height_difference)
    l0 = check_finite("unstretched_length [m]", unstretched_length, positive=True)
    ea = check_finite("EA [N]", EA, positive=True)
    w = check_finite("weight_per_length [N/m]", weight_per_length, positive=True)

    h0, v0 = initial_reactions(span, hd, l0, w * l0, ea / l0)
    # Work in (log H, V / (w L0)) so that H stays positive and both unknowns are O(1).
    wl = w * l0

    def fun(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        h = math.exp(y[0])
        r, j = _irvine_residual(np.array([h, y[1] * wl]), span, hd, l0, ea, w)
        return r, j @ np.diag([h, wl])

    sol = root(fun, np.array([math.log(h0), v0 / wl]), jac=True, method="hybr",
               options={"xtol": 1e-15, "maxfev": 2000})
    y = sol.x
    r, j = fun(y)
    for _ in range(8):                       # Newton polish to round-off
        if not np.all(np.isfinite(r)):
            break
        y_new = y - np.linalg.solve(j, r)
        r_new, j_new = fun(y_new)
        if not np.all(np.isfinite(r_new)) or np.abs(r_new).max() >= np.abs(r).max():
            break
        y, r, j = y_new, r_new, j_new
    err = float(np.abs(r).max()) if np.all(np.isfinite(r)) else math.inf
    if not err <= 1e-12:
        raise RuntimeError(f"Irvine catenary: support mismatch {err:.3e} m, expected <= 1e-12 m "
                           f"({sol.message})")
    return IrvineCable(span=span, height_difference=hd, L0=l0, EA=ea, w=w, H=math.exp(y[0]),
                       V=y[1] * wl)


def irvine_catenary(span: float, height_difference: float, unstretched_length: float, EA: float,
                    weight_per_length: float,
                    s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Positions (x, z) [m] at Lagrangian coordinates ``s`` in [0, L0] [m] of
    Irvine's elastic catenary between (0, 0) and (span, height_difference).

    ``EA`` [N] axial stiffness, ``weight_per_length`` [N/m] per unstretched
    length.  With z up, V the upward reaction at (0, 0), T(s) = sqrt(H^2 + (w s - V)^2):

        x(s) = H s / EA + (H / w) [asinh((w s - V) / H) + asinh(V / H)]
        z(s) = (w s^2 / 2 - V s) / EA + (T(s) - T(0)) / w
    """
    s_arr = np.asarray(s, dtype=float)
    l0 = check_finite("unstretched_length [m]", unstretched_length, positive=True)
    if np.any(~np.isfinite(s_arr)) or np.any(s_arr < 0.0) or np.any(s_arr > l0 * (1.0 + 1e-12)):
        raise ValueError(
            f"s [m]: range [{s_arr.min()!r}, {s_arr.max()!r}], expected within [0, L0 = {l0!r}]")
    return solve_irvine(span, height_difference, l0, EA, weight_per_length).position(s_arr)


def inextensible_catenary(span: float, height_difference: float, length: float,
                          x: ArrayLike) -> np.ndarray:
    """z [m] at ``x`` [m] of the inextensible catenary of length ``length`` [m]
    between (0, 0) and (span, height_difference) (needs length > chord)."""
    l, h, big_l = float(span), float(height_difference), float(length)
    if not big_l > math.hypot(l, h):
        raise ValueError(f"length [m]: {length!r}, expected > chord = {math.hypot(l, h)!r}")
    target = math.sqrt(big_l * big_l - h * h)
    # 2 a sinh(l / 2a) = target; the left side decreases from inf to l as a grows
    f = lambda a: 2.0 * a * math.sinh(l / (2.0 * a)) - target  # noqa: E731
    a_lo = l / (2.0 * math.asinh(target / l) + 2.0)
    while f(a_lo) < 0.0:
        a_lo *= 0.5
    a_hi = l
    while f(a_hi) > 0.0:
        a_hi *= 2.0
    a = brentq(f, a_lo, a_hi, xtol=1e-16, rtol=4 * np.finfo(float).eps, maxiter=500)
    x0 = 0.5 * l - a * math.asinh(h / (2.0 * a * math.sinh(l / (2.0 * a))))
    return a * (np.cosh((np.asarray(x, dtype=float) - x0) / a) - math.cosh(x0 / a))


# -------------------------------------------------------------- discretisation


@dataclass(frozen=True)
class LumpedCable:
    """A lumped-mass chain standing for an elastic cable (arguments of
    :func:`elastic_chain_equilibrium`) and the Lagrangian coordinates
    ``s_nodes`` (N,) [m] of its masses on the cable."""

    anchor_a: np.ndarray
    anchor_b: np.ndarray
    rest_lengths: np.ndarray
    stiffness: np.ndarray
    masses: np.ndarray
    s_nodes: np.ndarray
    g: float

    def solve(self) -> ChainEquilibrium:
        """Equilibrium of this chain."""
        return solve_elastic_chain(self.anchor_a, self.anchor_b, self.rest_lengths, self.stiffness,
                                   self.masses, self.g)


def discretise_cable(span: float, height_difference: float, unstretched_length: float, EA: float,
                     weight_per_length: float, n_masses: int, g: float = 9.81) -> LumpedCable:
    """N = ``n_masses`` masses, N + 1 equal links of rest length L0 / (N + 1)
    [m] and stiffness EA / L_i [N/m]; each mass w L0 / ((N + 1) g) [kg] (the
    halves of the end links' weight go to the supports).  Supports (0, 0) and
    (span, height_difference) [m]."""
    n = int(n_masses)
    if n != n_masses or n < 1:
        raise ValueError(f"n_masses: {n_masses!r}, expected an integer >= 1")
    l0 = check_finite("unstretched_length [m]", unstretched_length, positive=True)
    ea = check_finite("EA [N]", EA, positive=True)
    w = check_finite("weight_per_length [N/m]", weight_per_length)
    g = check_finite("g [m/s^2]", g, positive=True)
    seg = l0 / (n + 1)
    return LumpedCable(
        anchor_a=np.zeros(2),
        anchor_b=np.array([float(span), float(height_difference)]),
        rest_lengths=np.full(n + 1, seg),
        stiffness=np.full(n + 1, ea / seg),
        masses=np.full(n, w * seg / g),
        s_nodes=seg * np.arange(1, n + 1),
        g=g,
    )
