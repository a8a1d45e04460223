"""Three-element rheological unit (paper Sec. 2, Fig. 1) and its exact time step.

The unit is a Kelvin-Voigt element (spring ``k1`` [N/m] parallel to dashpot
``c1`` [N s/m]) in series with a dashpot ``c2`` [N s/m].  ``c1 = 0`` is the
Maxwell model the paper identifies for fondant icing; ``c2 = inf`` is a
Kelvin-Voigt solid (and with ``c1 = 0`` a purely elastic spring).

State of one unit over its rest length ``L0`` [m]:

* ``e1`` [m]: elongation of the Kelvin-Voigt element (recoverable),
* ``p``  [m]: elongation of the series dashpot c2 (plastic, non-recoverable).

Its free length (the length at which it carries no force at rest) is
``L0 + e1 + p``.  A longer unit is taut; a shorter one is slack and carries no
force: a thin sheet buckles rather than carry compression.

:func:`elongation_step` advances the unit over a time step ``dt`` during which
its length changes linearly in time.  Under that assumption the update is the
exact solution of the unit's linear ODE (paper Eq. 2):

    (c1 + c2) de1/dt = c2 dl/dt - k1 e1,          F = c2 dp/dt = k1 e1 + c1 de1/dt

so a constant-rate pull reproduces Eq. 5 to round-off for any ``dt``
(:mod:`rheo_shaping.material.closed_forms` holds Eq. 3-13, :mod:`rheo_shaping.material.response`
drives a unit with whole elongation or force histories, and
:mod:`rheo_shaping.material.burgers` adds the four-element Burgers model).  The
force at the end of the step is affine in the elongation ``delta`` taken during
the step, ``F = F0 + S delta`` (taut units), which is what the sheet solver
needs to build its implicit step.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params.validators import check_non_negative, check_positive, check_time_step

#: Rest length of the tensile specimen the paper's constants belong to [m].
SPECIMEN_LENGTH_M = 0.1


@dataclass(frozen=True)
class ThreeElement:
    """Constants of a three-element unit of rest length ``length`` [m].

    ``k1`` [N/m], ``c1`` [N s/m], ``c2`` [N s/m]; ``c2 = inf`` means no plastic
    flow.  The paper's fondant icing on the 0.1 m specimen is
    ``ThreeElement(k1=95.0, c1=0.0, c2=1.30e3)``.
    """

    k1: float
    c1: float
    c2: float
    length: float = SPECIMEN_LENGTH_M

    def __post_init__(self) -> None:
        check_positive("k1 [N/m]", self.k1)
        check_non_negative("c1 [N s/m]", self.c1)
        check_positive("c2 [N s/m]", self.c2, allow_inf=True)
        check_positive("length [m]", self.length)

    @property
    def is_maxwell(self) -> bool:
        """True when ``c1 == 0`` (spring in series with a dashpot)."""
        return self.c1 == 0.0

    def scaled(self, length: float) -> "ThreeElement":
        """The same material over another rest length [m].

        A spring of constant k over L0 acts as k*L0/l over length l, and so do
        the dashpots (the material's modulus and viscosity are what stay).
        """
        check_positive("length [m]", length)
        s = self.length / length
        return ThreeElement(self.k1 * s, self.c1 * s, self.c2 * s, length)


def maxwell(k: float, c: float, length: float = SPECIMEN_LENGTH_M) -> ThreeElement:
    """Maxwell model: spring ``k`` [N/m] in series with dashpot ``c`` [N s/m].

    It is the ``c1 = 0`` case of the three-element unit (paper Sec. 3.4.2,
    the model the paper identifies for fondant icing), so it is returned as
    ``ThreeElement(k1=k, c1=0, c2=c, length=length)``.
    """
    return ThreeElement(k, 0.0, c, length)


def step_factors(k1, c1, c2, dt):
    """Factors of the exact step, vectorised over units.

    Returns ``(r, eps, g)`` with ``r = c2/(c1+c2)``, ``x = k1 dt/(c1+c2)``,
    ``eps = exp(-x)`` and ``g = (1 - eps)/x`` (``g -> 1`` as ``x -> 0``).
    ``c2 = inf`` gives ``r = 1, eps = 1, g = 1``.  ``exp(-x)`` is the decay
    ``exp(-k1 t/(c1+c2))`` of paper Eq. 3-5 over one step.  A ``dt`` that is
    not positive and finite raises :class:`ValueError`.
    """
    check_time_step(dt)
    k1 = np.asarray(k1, dtype=float)
    c1 = np.asarray(c1, dtype=float)
    c2 = np.asarray(c2, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = 1.0 / (1.0 + c1 / c2)
        x = k1 * dt / (c1 + c2)
    x = np.where(np.isfinite(x), x, 0.0)
    eps = np.exp(-x)
    small = x < 1e-8
    g = np.where(small, 1.0 - 0.5 * x, -np.expm1(-x) / np.where(small, 1.0, x))
    return r, eps, g


def step_coefficients(k1, c1, c2, e1, dt):
    """Affine force law of a taut unit over one step: ``F_end = F0 + S*delta``.

    ``delta`` [m] is the elongation taken during the step (length at the end
    minus the free length at the start).  Returns ``(F0 [N], S [N/m])``.
    """
    r, eps, g = step_factors(k1, c1, c2, dt)
    k1 = np.asarray(k1, dtype=float)
    c1 = np.asarray(c1, dtype=float)
    F0 = k1 * r * eps * np.asarray(e1, dtype=float)
    S = r * (k1 * r * g + c1 / dt)
    return F0, S


def elongation_step(k1, c1, c2, e1, p, delta, dt):
    """Advance units whose length grows linearly by ``delta`` [m] over ``dt`` [s].

    Exact for the linear ODE of the unit while it stays taut.  A unit whose
    end force would be negative is slack at the end of the step: it carries
    no force, its dashpot c2 does not flow, and its Kelvin-Voigt part relaxes
    freely (at once when ``c1 = 0``).

    Returns ``(F [N], e1_new [m], p_new [m])``.
    """
    k1 = np.asarray(k1, dtype=float)
    c1 = np.asarray(c1, dtype=float)
    e1 = np.asarray(e1, dtype=float)
    p = np.asarray(p, dtype=float)
    delta = np.asarray(delta, dtype=float)
    r, eps, g = step_factors(k1, c1, c2, dt)
    e1_taut = eps * e1 + r * g * delta
    F = k1 * r * e1_taut + r * c1 * delta / dt
    taut = F > 0.0
    with np.errstate(divide="ignore", over="ignore"):
        relax = np.where(c1 > 0.0, np.exp(-k1 * dt / np.where(c1 > 0.0, c1, 1.0)), 0.0)
    e1_new = np.where(taut, e1_taut, e1 * relax)
    p_new = np.where(taut, p + delta - (e1_taut - e1), p)
    return np.where(taut, F, 0.0), e1_new, p_new
