"""Initial shape of the sheet draped over the cake's top edge (t = 0).

The centreline runs flat on the cake top from the top bond, around the
filleted edge (radius fillet + r), and then down to the workplane bond: along
the tangent line when the sheet is just long enough, or along a catenary of
the extra length (``excess_length``).  Links are unstretched at t = 0, as in
the paper's Fig. 13 a); the sheet then sags under gravity (test case 1).
"""
from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np


@dataclass(frozen=True)
class Drape:
    """A drape path: sample it by arc length with :meth:`points`."""

    top_bond: np.ndarray      # (2,) m
    bottom_bond: np.ndarray   # (2,) m
    arc_centre: np.ndarray    # (2,) m, fillet centre
    arc_radius: float         # m, centreline radius around the fillet
    theta_tangent: float      # rad, where the free part leaves the fillet
    excess: float             # m

    @property
    def flat_length(self) -> float:
        return float(self.arc_centre[0] - self.top_bond[0])

    @property
    def arc_length(self) -> float:
        return float(self.arc_radius * (0.5 * np.pi - self.theta_tangent))

    @property
    def tangent_point(self) -> np.ndarray:
        t = self.theta_tangent
        return self.arc_centre + self.arc_radius * np.array([np.cos(t), np.sin(t)])

    @property
    def free_chord(self) -> float:
        return float(np.linalg.norm(self.bottom_bond - self.tangent_point))

    @property
    def length(self) -> float:
        """Total centreline length [m] (the sheet's rest length)."""
        return self.flat_length + self.arc_length + self.free_chord + self.excess

    def points(self, s: np.ndarray) -> np.ndarray:
        """Centreline points (M, 2) [m] at arc lengths ``s`` from the top bond."""
        s = np.asarray(s, dtype=float)
        out = np.empty((s.size, 2))
        a1 = self.flat_length
        a2 = a1 + self.arc_length
        flat = s <= a1
        out[flat, 0] = self.top_bond[0] + s[flat]
        out[flat, 1] = self.top_bond[1]
        arc = (s > a1) & (s <= a2)
        th = 0.5 * np.pi - (s[arc] - a1) / self.arc_radius
        out[arc] = self.arc_centre + self.arc_radius * np.c_[np.cos(th), np.sin(th)]
        free = s > a2
        out[free] = self._free_points(s[free] - a2)
        return out

    def _free_points(self, s: np.ndarray) -> np.ndarray:
        p0, p1 = self.tangent_point, self.bottom_bond
        chord = p1 - p0
        L = self.free_chord + self.excess
        if self.excess <= 1e-12 * L:
            return p0 + (s / self.free_chord)[:, None] * chord
        dx, dz = chord
        # catenary z = a cosh((x - x0)/a) + z0 through p0, p1 with arc length L
        target = np.sqrt(L * L - dz * dz)
        # sinh overflows past 710: the bracket starts at dx/(2a) = 700
        a = _catenary_parameter(dx, target)
        # x0 from the height difference: dz = a (cosh(u1) - cosh(u0)), u = (x - x0)/a
        m = np.arctanh(dz / L)          # (u0 + u1)/2
        u0 = m - dx / (2 * a)
        x0 = p0[0] - a * u0
        s0 = a * np.sinh(u0)
        u = np.arcsinh((s0 + s) / a)
        x = x0 + a * u
        z = p0[1] + a * (np.cosh(u) - np.cosh(u0))
        return np.c_[x, z]


def _catenary_parameter(dx: float, target: float) -> float:
    """The a [m] with 2 a sinh(dx / (2 a)) = target [m] (> dx > 0): bisection in log a
    to round-off (the left side falls monotonically in a); no scipy import at start-up."""
    f = lambda a: 2.0 * a * math.sinh(dx / (2.0 * a)) - target  # noqa: E731
    lo, hi = dx / 1400.0, dx * 1e6       # sinh overflows past 710: start at dx/(2a) = 700
    if not (f(lo) > 0.0 > f(hi)):
        raise ValueError(f"catenary: no parameter for span {dx!r} m and length {target!r} m")
    for _ in range(200):
        mid = math.sqrt(lo * hi)
        if not lo < mid < hi:
            break
        if f(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return hi if abs(f(hi)) < abs(f(lo)) else lo


def make_drape(cake_height: float, fillet_radius: float, sphere_radius: float,
               top_bond_x: float, bottom_bond_x: float, excess: float = 0.0) -> Drape:
    """The drape of a sheet of centreline offset ``sphere_radius`` [m] from the cake."""
    r = sphere_radius
    centre = np.array([-fillet_radius, cake_height - fillet_radius])
    rho = fillet_radius + r
    top = np.array([top_bond_x, cake_height + r])
    bottom = np.array([bottom_bond_x, r])
    cb = bottom - centre
    dist = float(np.hypot(*cb))
    if dist <= rho:
        raise ValueError(f"workplane bond {bottom.tolist()} lies inside the rounded edge")
    theta = float(np.arctan2(cb[1], cb[0]) + np.arccos(rho / dist))
    theta = min(theta, 0.5 * np.pi)
    return Drape(top, bottom, centre, rho, theta, float(excess))
