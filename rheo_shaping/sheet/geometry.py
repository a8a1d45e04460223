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
    "RoundedConvexPolygon",
    "circle",
    "rounded_rectangle",
    "convex_polygon",
]


def _as_points(points: Any) -> np.ndarray:
    """Points as a float (M, 2) array; a single (2,) point becomes (1, 2)."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        if p.shape == (2,):
            return p.reshape(1, 2)
        raise ValueError(f"points: shape {p.shape}, expected (M, 2) [m]")
    return p


def _distance(shape: Any, points: Any, offset: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(d (M,) [m], n (M, 2)) of ``shape`` at ``points`` from the compiled step's own shape
    evaluation (:func:`rheo_shaping.sheet.kernel.shape_eval`): one implementation for both."""
    from . import kernel
    p = np.ascontiguousarray(_as_points(points))
    ox, oz = (float(v) for v in offset)
    kind, rad, verts = shape.kernel_description()
    table = shape.__dict__.get("_table")
    if table is None:
        table = kernel.shape_table(verts)
        object.__setattr__(shape, "_table", table)
    d, n, _ = kernel.shape_eval_many(kind, len(verts), table, rad, p, ox, oz)
    return d, n


def _check_n_points(n_points: int, minimum: int) -> int:
    n = int(n_points)
    if n != n_points or n < minimum:
        raise ValueError(f"n_points: {n_points!r}, expected an integer >= {minimum}")
    return n


def _sample_pieces(kinds: list[tuple], lengths: np.ndarray, n_points: int,
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


@dataclass(frozen=True)
class Cake:
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

    def signed_distance(self, points: Any,
                        offset: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance ``d`` (M,) [m] and outward unit normal ``n`` (M, 2)."""
        return _distance(self, points, offset)

    def contains(self, points: Any, offset: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
        """True for points inside or on the boundary."""
        return self.signed_distance(points, offset)[0] <= 0.0

    def kernel_description(self) -> tuple[int, float, np.ndarray]:
        """(kind 0, fillet radius [m], quadrant corner (1, 2) [m]) for the compiled step
        (rheo_shaping.sheet.kernel.shape_eval): the quadrant grown by the fillet radius."""
        return 0, float(self.fillet_radius), self._centre.reshape(1, 2).copy()

    def outline(self, n_points: int = 64, closed: bool = False) -> np.ndarray:
        """Boundary points (K, 2) [m] from (-top_length, height) along the top,
        round the fillet and down the wall to (0, 0); ``closed=True`` continues
        along the workplane and up the far side, back to the start (not repeated)."""
        n_points = _check_n_points(n_points, 4)
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
        return _sample_pieces(kinds, np.array(lengths), n_points, closed)


# ---------------------------------------------------------------------- workplane


@dataclass(frozen=True)
class Workplane:
    """The half-plane z <= 0.  ``x_min``/``x_max`` [m] only bound the plotted outline."""

    x_min: float = -0.1
    x_max: float = 0.3

    def __post_init__(self) -> None:
        lo = check_finite("x_min [m]", self.x_min)
        hi = check_finite("x_max [m]", self.x_max)
        if not hi > lo:
            raise ValueError(f"x_max [m]: {self.x_max!r}, expected > x_min = {lo!r}")

    def signed_distance(self, points: Any,
                        offset: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance ``d = z - offset_z`` (M,) [m] and normal (0, 1) (M, 2)."""
        return _distance(self, points, offset)

    def contains(self, points: Any, offset: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
        """True for points on or below the plane."""
        return self.signed_distance(points, offset)[0] <= 0.0

    def kernel_description(self) -> tuple[int, float, np.ndarray]:
        """(kind 1, 0, no vertices) for the compiled step: the half-plane z <= 0."""
        return 1, 0.0, np.zeros((0, 2))

    def outline(self, n_points: int = 2) -> np.ndarray:
        """Points (n_points, 2) [m] along z = 0 from x_min to x_max."""
        n_points = _check_n_points(n_points, 2)
        x = np.linspace(self.x_min, self.x_max, n_points)
        return np.column_stack((x, np.zeros_like(x)))


# ------------------------------------------------------------------------- tools


@dataclass(frozen=True)
class RoundedConvexPolygon:
    """Minkowski sum of a convex polygon and a disc of radius ``radius`` [m].

    ``vertices`` (K, 2) [m], counter-clockwise, in the tool's own frame
    relative to its reference point (a flat sequence x0, z0, x1, z1, ... is
    accepted too).  K = 1 is a circle of radius ``radius`` centred on the
    vertex, K = 2 a capsule; both need ``radius > 0``.  K >= 3 must be strictly
    convex (no repeated or collinear vertices) and counter-clockwise.
    """

    vertices: tuple
    radius: float = 0.0
    _v: np.ndarray = field(init=False, repr=False, compare=False)
    _e: np.ndarray = field(init=False, repr=False, compare=False)
    _nrm: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        try:
            v = np.array(self.vertices, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"vertices: {self.vertices!r}, expected (K, 2) numbers [m]") from exc
        if v.ndim == 1 and v.size % 2 == 0 and v.size > 0:
            v = v.reshape(-1, 2)
        if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 1:
            raise ValueError(
                f"vertices: shape {np.shape(self.vertices)}, expected (K, 2) with K >= 1 [m]")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"vertices: {v.tolist()!r}, expected finite numbers [m]")
        r = check_finite("radius [m]", self.radius, non_negative=True)
        k = v.shape[0]
        if k <= 2 and r <= 0.0:
            raise ValueError(
                f"radius [m]: {self.radius!r}, expected > 0 for a polygon of {k} vertex(es)")
        e = np.roll(v, -1, axis=0) - v
        len2 = np.einsum("ij,ij->i", e, e)
        if k >= 2:
            scale = max(float(np.abs(v).max()), float(np.sqrt(len2.max())), 1e-300)
            short = np.flatnonzero(np.sqrt(len2) <= 1e-12 * scale)
            if short.size:
                i = int(short[0])
                raise ValueError(f"vertices: vertex {i} {v[i].tolist()} repeats vertex "
                                 f"{(i + 1) % k} "
                                 f"{v[(i + 1) % k].tolist()}, expected distinct vertices")
        if k >= 3:
            e_next = np.roll(e, -1, axis=0)
            cross = e[:, 0] * e_next[:, 1] - e[:, 1] * e_next[:, 0]
            dot = np.einsum("ij,ij->i", e, e_next)
            turn = np.arctan2(cross, dot)
            tol = 1e-12 * len2.max()
            if np.all(cross < -tol):
                raise ValueError(f"vertices: {v.tolist()!r} are clockwise, expected "
                                 "counter-clockwise "
                                 "(reverse their order)")
            bad = np.flatnonzero(cross <= tol)
            if bad.size:
                i = (int(bad[0]) + 1) % k
                raise ValueError(f"vertices: vertex {i} {v[i].tolist()} turns clockwise or is "
                                 "collinear "
                                 f"(cross product {cross[bad[0]]:.3g} m^2), expected a strictly "
                                 "convex "
                                 "counter-clockwise polygon")
            if abs(turn.sum() - 2.0 * math.pi) > 1e-6:
                raise ValueError(f"vertices: {v.tolist()!r} wind {turn.sum() / (2 * math.pi):.3g} "
                                 "times, "
                                 "expected a simple convex polygon (winding once)")
        object.__setattr__(self, "vertices", tuple(tuple(float(c) for c in row) for row in v))
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "_v", v)
        object.__setattr__(self, "_e", e)
        ln = np.sqrt(len2)
        nrm = np.column_stack((e[:, 1], -e[:, 0])) / np.where(ln > 0, ln, 1.0)[:, None]
        object.__setattr__(self, "_nrm", nrm)

    # constructors --------------------------------------------------------

    @classmethod
    def circle(cls, radius: float) -> "RoundedConvexPolygon":
        """Disc of radius ``radius`` [m] centred on the reference point."""
        check_finite("radius [m]", radius, positive=True)
        return cls(((0.0, 0.0),), float(radius))

    @classmethod
    def rounded_rectangle(cls, width: float, height: float,
                          corner_radius: float = 0.0) -> "RoundedConvexPolygon":
        """Rectangle ``width`` (x) by ``height`` (z) [m] centred on the reference
        point, corners rounded with ``corner_radius`` [m] <= min(width, height) / 2."""
        w = check_finite("width [m]", width, positive=True)
        h = check_finite("height [m]", height, positive=True)
        r = check_finite("corner_radius [m]", corner_radius, non_negative=True)
        if r > 0.5 * min(w, h):
            raise ValueError(f"corner_radius [m]: {corner_radius!r}, expected <= min(width, "
                             "height) / 2 = "
                             f"{0.5 * min(w, h)!r}")
        a, b = 0.5 * w - r, 0.5 * h - r
        if a <= 1e-12 * w and b <= 1e-12 * h:
            verts: tuple = ((0.0, 0.0),)
        elif a <= 1e-12 * w:
            verts = ((0.0, -b), (0.0, b))
        elif b <= 1e-12 * h:
            verts = ((-a, 0.0), (a, 0.0))
        else:
            verts = ((-a, -b), (a, -b), (a, b), (-a, b))
        return cls(verts, r)

    @classmethod
    def convex_polygon(cls, vertices: Any, radius: float = 0.0) -> "RoundedConvexPolygon":
        """Convex polygon ``vertices`` (K, 2) [m] (CCW) grown by ``radius`` [m]."""
        return cls(vertices, radius)

    # queries ---------------------------------------------------------------

    @property
    def n_vertices(self) -> int:
        return int(self._v.shape[0])

    def signed_distance(self, points: Any,
                        offset: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance ``d`` (M,) [m] and outward unit normal ``n`` (M, 2).

        Outside the polygon ``d + radius`` is the distance to its nearest
        boundary point and ``n`` points from that point; inside, ``d + radius``
        is the largest signed edge-line distance and ``n`` that edge's normal.
        """
        return _distance(self, points, offset)

    def contains(self, points: Any, offset: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
        """True for points inside or on the boundary."""
        return self.signed_distance(points, offset)[0] <= 0.0

    def kernel_description(self) -> tuple[int, float, np.ndarray]:
        """(kind 2, radius [m], vertices (K, 2) [m], CCW) for the compiled step
        (rheo_shaping.sheet.kernel.shape_eval): the polygon grown by the disc."""
        return 2, float(self.radius), self._v.copy()

    def outline(self, n_points: int = 64, offset: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
        """Closed boundary (n_points, 2) [m], counter-clockwise, last point not
        repeated; every edge end and arc end is included.  ``offset`` translates it."""
        v, e, nrm, r = self._v, self._e, self._nrm, self.radius
        k = v.shape[0]
        kinds: list[tuple] = []
        lengths: list[float] = []
        if k == 1:
            kinds.append(("arc", v[0], r, 0.0, 2.0 * math.pi))
            lengths.append(2.0 * math.pi * r)
        else:
            phi = np.arctan2(nrm[:, 1], nrm[:, 0])
            for i in range(k):
                # edge i from v_i to v_{i+1}, shifted out by r, then the arc round v_{i+1}
                kinds.append(("seg", v[i] + r * nrm[i], v[(i + 1) % k] + r * nrm[i]))
                lengths.append(float(np.sqrt(e[i] @ e[i])))
                dphi = (phi[(i + 1) % k] - phi[i]) % (2.0 * math.pi)
                if k == 2:
                    dphi = math.pi
                kinds.append(("arc", v[(i + 1) % k], r, float(phi[i]), float(dphi)))
                lengths.append(r * dphi)
        n_points = _check_n_points(n_points, max(3, sum(1 for x in lengths if x > 0)))
        return _sample_pieces(kinds, np.array(lengths), n_points, True) + np.asarray(offset, float)


def circle(radius: float) -> RoundedConvexPolygon:
    """Disc tool of radius ``radius`` [m] centred on its reference point."""
    return RoundedConvexPolygon.circle(radius)


def rounded_rectangle(width: float, height: float,
                      corner_radius: float = 0.0) -> RoundedConvexPolygon:
    """Rounded-rectangle tool ``width`` x ``height`` [m] centred on its reference point."""
    return RoundedConvexPolygon.rounded_rectangle(width, height, corner_radius)


def convex_polygon(vertices: Any, radius: float = 0.0) -> RoundedConvexPolygon:
    """Convex polygon tool (vertices (K, 2) [m], CCW) grown by ``radius`` [m]."""
    return RoundedConvexPolygon.convex_polygon(vertices, radius)
