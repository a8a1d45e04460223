"""2-D rigid obstacles in frame ``cake``; their signed distance is the compiled step's own.

Frame ``cake`` (docs/interfaces.md): x horizontal, outward from the cake's
side wall (the wall is x = 0, the cake fills x <= 0 up to its height), z up
from the workplane z = 0.  SI units (m).

Every shape offers

* ``signed_distance(points, offset=(0, 0)) -> (d, n)``: for points (M, 2) [m],
  ``d`` (M,) [m] is positive outside and negative inside, ``n`` (M, 2) is the
  unit outward normal, the gradient of ``d`` wherever ``d`` is differentiable
  (inside a polygon it is the outward normal of the nearest edge, outside a
  vertex it is radial).  ``offset`` (2,) [m] translates the shape (the tool's
  pose; the orientation is fixed).
* ``contains(points, offset=(0, 0)) -> bool (M,)``: ``d <= 0``.
* ``outline(n_points) -> (K, 2)``: boundary points for plots and RViz markers.

Every shape also gives ``kernel_description() -> (kind, radius, vertices)``,
the small array description the compiled sheet step evaluates
(:func:`rheo_shaping.sheet.kernel.shape_eval`, which also gives the curvature of the
distance's level sets); ``signed_distance`` calls that same compiled function.

Shapes:

* :class:`Cake`: the region x <= 0, z <= height whose top outer corner
  (0, height) is rounded by a fillet tangent to the top and to the wall.
* :class:`Workplane`: the half-plane z <= 0.
* :class:`RoundedConvexPolygon`: Minkowski sum of a convex polygon and a disc,
  which covers the tools: :func:`circle`, :func:`rounded_rectangle`,
  :func:`convex_polygon`.  One vertex is a circle, two vertices a capsule
  (stadium).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..params.validators import check_finite

__all__ = [
    "Cake",
    "Workplane",
]


def as_points(points: Any) -> np.ndarray:
    """Points as a float (M, 2) array; a single (2,) point becomes (1, 2)."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        if p.shape == (2,):
            return p.reshape(1, 2)
        raise ValueError(f"points: shape {p.shape}, expected (M, 2) [m]")
    return p


def distance(shape: Any, points: Any, offset: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(d (M,) [m], n (M, 2)) of ``shape`` at ``points`` from the compiled step's own shape
    evaluation (:func:`rheo_shaping.sheet.kernel.shape_eval`): one implementation for both."""
    from . import kernel
    p = np.ascontiguousarray(as_points(points))
    ox, oz = (float(v) for v in offset)
    kind, rad, verts = shape.kernel_description()
    table = shape.__dict__.get("_table")
    if table is None:
        table = kernel.shape_table(verts)
        object.__setattr__(shape, "_table", table)
    d, n, _ = kernel.shape_eval_many(kind, len(verts), table, rad, p, ox, oz)
    return d, n


def check_n_points(n_points: int, minimum: int) -> int:
    n = int(n_points)
    if n != n_points or n < minimum:
        raise ValueError(f"n_points: {n_points!r}, expected an integer >= {minimum}")
    return n


def sample_pieces(kinds: list[tuple], lengths: np.ndarray, n_points: int,
                  closed: bool) -> np.ndarray:
    """Sample a piecewise boundary (segments and arcs) with ``n_points`` points.

    ``kinds[i]`` is ``("seg", a, b)`` or ``("arc", centre, radius, phi0, dphi)``.
    Every piece of positive length gets its start point; the rest of the
    points are shared by arc length (largest remainder).  ``closed=False``
    appends the end point of the last piece.
    """
    lengths = np.asarray(lengths, dtype=float)
    pos = np.flatnonzero(lengths > 0.0)
    n_free = n_points - len(pos) - (0 if closed else 1)
    if n_free < 0:
        raise ValueError(
            f"n_points: {n_points}, expected >= {len(pos) + (0 if closed else 1)} for this "
            "outline")
    share = n_free * lengths[pos] / lengths[pos].sum()
    extra = np.floor(share).astype(int)
    rest = n_free - extra.sum()
    if rest > 0:
        extra[np.argsort(extra - share)[:rest]] += 1
    out = []
    for j, i in enumerate(pos):
        t = np.arange(extra[j] + 1) / (extra[j] + 1)
        kind = kinds[i]
        if kind[0] == "seg":
            a, b = kind[1], kind[2]
            out.append(a + t[:, None] * (b - a))
        else:
            c, r, phi0, dphi = kind[1], kind[2], kind[3], kind[4]
            phi = phi0 + t * dphi
            out.append(c + r * np.column_stack((np.cos(phi), np.sin(phi))))
    if not closed:
        kind = kinds[pos[-1]]
        if kind[0] == "seg":
            out.append(kind[2][None, :])
        else:
            c, r, phi = kind[1], kind[2], kind[3] + kind[4]
            out.append(c + r * np.array([[math.cos(phi), math.sin(phi)]]))
    return np.vstack(out)


# --------------------------------------------------------------------------- cake


class _Region:
    """An obstacle region: signed distance and containment from :func:`distance`."""

    def signed_distance(self, points: Any,
                        offset: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance ``d`` (M,) [m] (negative inside) and outward unit normal (M, 2)."""
        return distance(self, points, offset)

    def contains(self, points: Any, offset: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
        """True for points inside or on the boundary."""
        return self.signed_distance(points, offset)[0] <= 0.0


@dataclass(frozen=True)
class Cake(_Region):
    """The cake's cross-section: x <= 0, z <= ``height`` [m], top outer corner filleted.

    ``fillet_radius`` [m] (0 for a sharp edge) rounds the corner (0, height)
    with an arc tangent to the top z = height and to the wall x = 0, centred at
    (-fillet_radius, height - fillet_radius).  ``top_length`` [m] is how far
    the top extends to -x; it only bounds the plotted outline: for distances
    the region is unbounded towards -x and -z (it is convex).
    """

    height: float
    fillet_radius: float = 0.0
    top_length: float = 0.09
    _centre: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        h = check_finite("height [m]", self.height, positive=True)
        r = check_finite("fillet_radius [m]", self.fillet_radius, non_negative=True)
        tl = check_finite("top_length [m]", self.top_length, positive=True)
        if r > h:
            raise ValueError(
                f"fillet_radius [m]: {self.fillet_radius!r}, expected <= height = {h!r}")
        if r > tl:
            raise ValueError(
                f"fillet_radius [m]: {self.fillet_radius!r}, expected <= top_length = {tl!r}")
        # The region is the quadrant {x <= -r, z <= h - r} grown by a disc of radius r.
        object.__setattr__(self, "_centre", np.array([-r, h - r]))

    @classmethod
    def of(cls, cake) -> "Cake":
        """The cross-section of a cell's cake (``CakeParams``: height, fillet radius [m];
        its radius [m] bounds the plotted top)."""
        return cls(cake.height, cake.fillet_radius, cake.radius)

    def kernel_description(self) -> tuple[int, float, np.ndarray]:
        """(kind 0, fillet radius [m], quadrant corner (1, 2) [m]) for the compiled step
        (rheo_shaping.sheet.kernel.shape_eval): the quadrant grown by the fillet radius."""
        return 0, float(self.fillet_radius), self._centre.reshape(1, 2).copy()

    def outline(self, n_points: int = 64, closed: bool = False) -> np.ndarray:
        """Boundary points (K, 2) [m] from (-top_length, height) along the top,
        round the fillet and down the wall to (0, 0); ``closed=True`` continues
        along the workplane and up the far side, back to the start (not repeated)."""
        n_points = check_n_points(n_points, 4)
        h, r, tl = float(self.height), float(self.fillet_radius), float(self.top_length)
        c = self._centre
        kinds: list[tuple] = [
            ("seg", np.array([-tl, h]), np.array([-r, h])),
            ("arc", c, r, 0.5 * math.pi, -0.5 * math.pi),
            ("seg", np.array([0.0, h - r]), np.array([0.0, 0.0])),
        ]
        lengths = [tl - r, 0.5 * math.pi * r, h - r]
        if closed:
            kinds += [("seg", np.array([0.0, 0.0]), np.array([-tl, 0.0])),
                      ("seg", np.array([-tl, 0.0]), np.array([-tl, h]))]
            lengths += [tl, h]
        return sample_pieces(kinds, np.array(lengths), n_points, closed)


# ---------------------------------------------------------------------- workplane


@dataclass(frozen=True)
class Workplane(_Region):
    """The half-plane z <= 0.  ``x_min``/``x_max`` [m] only bound the plotted outline."""

    x_min: float = -0.1
    x_max: float = 0.3

    def __post_init__(self) -> None:
        lo = check_finite("x_min [m]", self.x_min)
        hi = check_finite("x_max [m]", self.x_max)
        if not hi > lo:
            raise ValueError(f"x_max [m]: {self.x_max!r}, expected > x_min = {lo!r}")

    def kernel_description(self) -> tuple[int, float, np.ndarray]:
        """(kind 1, 0, no vertices) for the compiled step: the half-plane z <= 0."""
        return 1, 0.0, np.zeros((0, 2))

    def outline(self, n_points: int = 2) -> np.ndarray:
        """Points (n_points, 2) [m] along z = 0 from x_min to x_max."""
        n_points = check_n_points(n_points, 2)
        x = np.linspace(self.x_min, self.x_max, n_points)
        return np.column_stack((x, np.zeros_like(x)))
