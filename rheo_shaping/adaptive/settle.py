"""The settled sheet of nearby materials, to first order: what the closed loop's model runs
start from.

Every run of the estimate (:mod:`.estimator`: its residual, one forward difference per
knob, each trial step) starts from the sheet settled under gravity with its own material
(:func:`rheo_shaping.sheet.simulation.settled_state`: 500 inertial steps, about 60 % of a
refresh's CPU time when each run settles again).  Over the small moves of theta =
(ln k1/k1_0, ln c2/c2_0, ln m/m_0) within a refresh the settled state is smooth in theta,
so it is taken to first order about a reference theta_r where it is exact,

    S(theta) = S(theta_r) + sum_i (S(theta_r + h e_i) - S(theta_r)) / h (theta_i - theta_r,i),

for |theta - theta_r|_inf <= ``radius``, and settled exactly (and cached) beyond it; the
reference moves to the estimate when a refresh starts farther than ``radius`` from it
(:meth:`LinearSettle.recentre`), or, for the re-planner's pessimistic corners, once a corner
has come to rest within half the radius of where it was at the re-plan before
(:meth:`LinearSettle.follow`: a reference costs four settles, a far corner one).  The error
is second order in the distance: within the radius 0.05 of the default cell's reference,
the masses within 3 um and the tensions within 0.2 mN of the exact settle (the camera's
noise is 0.2 mm, the force's 5 mN; test/adaptive/test_settle.py).  No ROS here.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np

from ..params.cell import CellParams
from ..sheet.chain import SheetState
from ..sheet.simulation import Simulation


def material_cell(base: CellParams, knobs: Sequence[float] | np.ndarray) -> CellParams:
    """``base`` with k1 [N/m], c2 [N s/m] and mass per length [kg/m] = ``knobs``."""
    k1, c2, m = (float(v) for v in knobs)
    return replace(base, material=replace(base.material, k1=k1, c2=c2),
                   sheet=replace(base.sheet, mass_per_length=m))


def knobs_of(cell: CellParams) -> np.ndarray:
    """(3,) the cell's k1 [N/m], c2 [N s/m] and mass per length [kg/m]."""
    return np.array([cell.material.k1, cell.material.c2, cell.sheet.mass_per_length])


def theta_of(base: CellParams, cell: CellParams) -> np.ndarray:
    """(3,) theta of ``cell``'s material about ``base``'s: ln of the knobs' ratios."""
    return np.log(knobs_of(cell) / knobs_of(base))


#: The state's arrays taken to first order (the rest: the reference's).
FIELDS = ("x", "v", "e1", "p", "tension", "contact")


class LinearSettle:
    """Settled sheets of ``cell`` with k1, c2 and the mass per length ``nominal * exp(theta)``
    (``material``: theta -> that cell), first order within ``radius`` of a reference."""

    def __init__(self, material, radius: float = 0.05, step: float = 0.02):
        if not (radius > 0.0 and step > 0.0):
            raise ValueError(f"LinearSettle: radius {radius!r} and step {step!r}: expected > 0")
        self._material = material
        self.radius = float(radius)
        self.step = float(step)
        self.theta_r: np.ndarray | None = None
        self._base: SheetState | None = None
        self._slopes: list[dict[str, np.ndarray]] = []
        self.exact_settles = 0          # settled states asked of the sheet core (the cost)
        self._last: np.ndarray | None = None     # follow()'s theta before

    @classmethod
    def about(cls, base: CellParams, **kw) -> "LinearSettle":
        """Settled sheets of ``base`` with its knobs scaled by exp(theta)."""
        nominal = knobs_of(base)
        return cls(lambda th: material_cell(base, nominal * np.exp(th)), **kw)

    def exact(self, theta: np.ndarray) -> SheetState:
        """The settled sheet at ``theta``, settled (cached per material by the sheet core)."""
        self.exact_settles += 1
        cell: CellParams = self._material(np.asarray(theta, float))
        return Simulation(cell).state

    def recentre(self, theta: np.ndarray) -> None:
        """The reference at ``theta`` unless it lies within ``radius`` of the present one."""
        theta = np.asarray(theta, float)
        if self.theta_r is not None and np.max(np.abs(theta - self.theta_r)) <= self.radius:
            return
        base = self.exact(theta)
        slopes = []
        for i in range(theta.size):
            th = theta.copy()
            th[i] += self.step
            moved = self.exact(th)
            slopes.append({f: (getattr(moved, f) - getattr(base, f)) / self.step
                           for f in FIELDS})
        self.theta_r, self._base, self._slopes = theta.copy(), base, slopes

    def follow(self, theta: np.ndarray) -> SheetState:
        """The settled sheet at ``theta`` of a point that moves from call to call (a
        pessimistic corner): the reference is moved to it once it stays within half the
        radius of its last place."""
        theta = np.asarray(theta, float)
        if self._last is not None and np.max(np.abs(theta - self._last)) <= 0.5 * self.radius:
            self.recentre(theta)
        self._last = theta.copy()
        return self.state(theta)

    def state(self, theta: np.ndarray) -> SheetState:
        """The settled sheet at ``theta`` (first order within ``radius`` of the reference,
        exact beyond it or before any reference)."""
        theta = np.asarray(theta, float)
        if self.theta_r is None or self._base is None or \
                np.max(np.abs(theta - self.theta_r)) > self.radius:
            return self.exact(theta)
        d = theta - self.theta_r
        base = self._base
        return replace(base, **{f: getattr(base, f) + sum(
            di * s[f] for di, s in zip(d, self._slopes)) for f in FIELDS})
