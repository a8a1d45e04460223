"""Response of one unit to an imposed elongation or force history.

Maxwell (``ThreeElement`` with ``c1 = 0``), three-element and Burgers units.
The histories are samples ``t`` [s] (strictly increasing) with values between
them either linear (``hold="linear"``, first-order hold) or, for forces, held
from one sample to the next (``hold="step"``).  The schemes are exact for
these inputs, whatever the sample spacing:

* imposed elongation: :func:`rheo_shaping.material.three_element.elongation_step`
  (three-element, Maxwell) and a matrix exponential (Burgers);
* imposed force: the exponential first-order hold of the Kelvin-Voigt ODE
  ``c1 de1/dt + k1 e1 = F`` and the integral of ``F/c2``.

The unit starts at rest and unstressed at ``t[0]``.  It carries tension
only: under an imposed elongation it goes slack (force 0) when the linear
law would push, and imposed forces must be >= 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .burgers import Burgers, burgers_elongation_step
from .three_element import ThreeElement, elongation_step


@dataclass(frozen=True)
class Response:
    """A unit's history at the sample times.

    ``t`` [s], ``elongation`` x [m] (length minus rest length), ``force`` F [N],
    ``plastic`` elongation p of the dashpot c2 [m].  At a step of a stepped
    force the values are those just after the step.
    """

    t: np.ndarray
    elongation: np.ndarray
    force: np.ndarray
    plastic: np.ndarray

    @property
    def recoverable(self) -> np.ndarray:
        """Elongation that is not plastic [m] (springs and Kelvin-Voigt part)."""
        return self.elongation - self.plastic


def check_history(t, values, name: str, unit: str) -> tuple[np.ndarray, np.ndarray]:
    """Validate a sampled history: finite, 1-D, same length, ``t`` strictly increasing."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(values, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(
            f"time samples t [s] with shape {t.shape}: expected a non-empty 1-D array")
    if y.shape != t.shape:
        raise ValueError(
            f"{name} [{unit}] with shape {y.shape}: expected the shape of t, {t.shape}")
    for arr, label, u in ((t, "time t", "s"), (y, name, unit)):
        bad = ~np.isfinite(arr)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"{label} [{u}] = {float(arr[i])!r} at sample {i}: expected a finite number")
    steps = np.diff(t)
    if (steps <= 0.0).any():
        i = int(np.argmax(steps <= 0.0)) + 1
        raise ValueError(f"time t [s] = {float(t[i])!r} at sample {i}: expected it to be greater "
                         "than "
                         f"the previous sample {float(t[i - 1])!r} (strictly increasing)")
    return t, y


def elongation_response(material: "ThreeElement | Burgers", t, elongation) -> Response:
    """Force of a unit whose elongation [m] follows ``elongation`` (linear between samples).

    The first sample sets the origin of plastic flow: the unit is unstressed
    at ``t[0]`` with ``p = elongation[0]``.
    """
    t, x = check_history(t, elongation, "elongation", "m")
    n = t.size
    F = np.zeros(n)
    P = np.zeros(n)
    P[0] = x[0]
    if isinstance(material, Burgers):
        b = material
        f, e1, p = 0.0, 0.0, float(x[0])
        cache: dict = {}
        j2 = b.j2
        for i in range(1, n):
            free = f * j2 + e1 + p
            f, e1, p = burgers_elongation_step(b, f, e1, p, x[i] - free, t[i] - t[i - 1], cache)
            F[i], P[i] = f, p
    else:
        m = material
        e1, p = 0.0, float(x[0])
        for i in range(1, n):
            f, e1, p = elongation_step(m.k1, m.c1, m.c2, e1, p, x[i] - (e1 + p), t[i] - t[i - 1])
            F[i], P[i] = float(f), float(p)
            e1, p = float(e1), float(p)
    return Response(t, x, F, P)


def _kv_hold(k1: float, c1: float, e1: float, F0: float, slope: float, h: float) -> float:
    """Exact Kelvin-Voigt elongation after ``h`` [s] with F = F0 + slope*s (FOH)."""
    lam_h = k1 * h / c1
    eps = math.exp(-lam_h)
    # h - (1 - eps)/lam = h (1 - g), g = (1 - eps)/(lam h); series for small lam h
    one_minus_g = lam_h / 2.0 - lam_h * lam_h / \
        6.0 if lam_h < 1e-4 else 1.0 + math.expm1(-lam_h) / lam_h
    return eps * e1 + (F0 / k1) * (-math.expm1(-lam_h)) + (slope / k1) * h * one_minus_g


def force_response(material: "ThreeElement | Burgers", t, force, hold: str = "linear") -> Response:
    """Elongation of a unit loaded by ``force`` [N] (>= 0).

    ``hold="linear"``: force linear between samples; ``hold="step"``:
    ``force[i]`` acts on ``[t[i], t[i+1])`` (a creep test put on at ``t[0]``
    and taken off at ``t1`` is ``t = [0, t1, ...]``, ``force = [F, 0, ...]``).
    """
    if hold not in ("linear", "step"):
        raise ValueError(f"hold = {hold!r}: expected 'linear' or 'step'")
    t, Fs = check_history(t, force, "force", "N")
    if (Fs < 0.0).any():
        i = int(np.argmax(Fs < 0.0))
        raise ValueError(
            f"force [N] = {float(Fs[i])!r} at sample {i}: expected >= 0 (the unit carries tension "
            "only)")
    k1, c1, c2 = material.k1, material.c1, material.c2
    j2 = material.j2 if isinstance(material, Burgers) else 0.0
    n = t.size
    X = np.zeros(n)
    P = np.zeros(n)
    e1 = 0.0 if c1 > 0.0 else Fs[0] / k1
    p = 0.0
    X[0] = Fs[0] * j2 + e1
    for i in range(1, n):
        h = t[i] - t[i - 1]
        F0 = Fs[i - 1]
        slope = (Fs[i] - F0) / h if hold == "linear" else 0.0
        impulse = F0 * h + 0.5 * slope * h * h           # integral of F over the step
        if not math.isinf(c2):
            p += impulse / c2
        e1 = _kv_hold(k1, c1, e1, F0, slope, h) if c1 > 0.0 else Fs[i] / k1
        X[i] = Fs[i] * j2 + e1 + p
        P[i] = p
    return Response(t, X, Fs.copy(), P)
