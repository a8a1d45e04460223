"""The tool's cross-section: a convex polygon grown by a radius (a disc, a rounded
rectangle, any convex polygon), with signed distance, normal, curvature and outline in
the frame of its reference point.  SI units (m).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..params.validators import check_finite
from .geometry import check_n_points, distance, sample_pieces


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
        return distance(self, points, offset)

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
        n_points = check_n_points(n_points, max(3, sum(1 for x in lengths if x > 0)))
        return sample_pieces(kinds, np.array(lengths), n_points, True) + np.asarray(offset, float)


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
