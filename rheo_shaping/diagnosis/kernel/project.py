"""Profile points projected on polylines (compiled): the residual's geometry."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .consts import JIT


@njit(**JIT)
def project(points, frame, lines):
    """Each point ``points[p]`` (P, 2) [m] projected on the polyline ``lines[frame[p]]``
    (F, K, 2) [m]: its nearest segment (the first of equal distance), then

    * ``dist`` (P,) [m]: the distance to the foot point, + on the polyline's left
      (the side of the normal (-t_z, t_x) of its direction t);
    * ``arc`` (P,) [m]: the foot point's arc length from the polyline's first node;
    * ``foot`` (P, 2) [m];
    * ``normal`` (P, 2): the unit left normal of the node tangents (central differences,
      one-sided at the ends) interpolated linearly in arc length to the foot point.
    """
    P = points.shape[0]
    F, K = lines.shape[0], lines.shape[1]
    cum = np.zeros((F, K))                 # each frame's arc length at its nodes [m]
    for f in range(F):
        for j in range(K - 1):
            cum[f, j + 1] = cum[f, j] + math.hypot(lines[f, j + 1, 0] - lines[f, j, 0],
                                                   lines[f, j + 1, 1] - lines[f, j, 1])
    dist = np.empty(P)
    arc = np.empty(P)
    foot = np.empty((P, 2))
    normal = np.empty((P, 2))
    for p in range(P):
        f = frame[p]
        px = points[p, 0]
        pz = points[p, 1]
        best = np.inf
        bj = 0
        bs = 0.0
        bfx = 0.0
        bfz = 0.0
        for j in range(K - 1):
            ax = lines[f, j, 0]
            az = lines[f, j, 1]
            sx = lines[f, j + 1, 0] - ax
            sz = lines[f, j + 1, 1] - az
            L2 = sx * sx + sz * sz
            s = ((px - ax) * sx + (pz - az) * sz) / (L2 if L2 > 0.0 else 1.0)
            s = min(max(s, 0.0), 1.0)
            fx = ax + s * sx
            fz = az + s * sz
            d2 = (px - fx) * (px - fx) + (pz - fz) * (pz - fz)
            if d2 < best:
                best, bj, bs, bfx, bfz = d2, j, s, fx, fz
        sx = lines[f, bj + 1, 0] - lines[f, bj, 0]
        sz = lines[f, bj + 1, 1] - lines[f, bj, 1]
        cross = sx * (pz - bfz) - sz * (px - bfx)
        sign = 1.0 if cross > 0.0 else (-1.0 if cross < 0.0 else 0.0)
        dist[p] = math.sqrt(best) * sign
        arc[p] = cum[f, bj] + bs * math.sqrt(sx * sx + sz * sz)
        foot[p, 0] = bfx
        foot[p, 1] = bfz
        tx0, tz0 = _tangent(lines, f, bj)
        tx1, tz1 = _tangent(lines, f, bj + 1)
        tx = tx0 + bs * (tx1 - tx0)
        tz = tz0 + bs * (tz1 - tz0)
        n = math.hypot(tx, tz)
        n = n if n > 0.0 else 1.0
        normal[p, 0] = -tz / n
        normal[p, 1] = tx / n
    return dist, arc, foot, normal


@njit(**JIT)
def _tangent(lines, f, k):
    """The polyline's node tangent at node ``k`` (np.gradient along the nodes)."""
    K = lines.shape[1]
    if k == 0:
        return lines[f, 1, 0] - lines[f, 0, 0], lines[f, 1, 1] - lines[f, 0, 1]
    if k == K - 1:
        return (lines[f, K - 1, 0] - lines[f, K - 2, 0],
                lines[f, K - 1, 1] - lines[f, K - 2, 1])
    return (0.5 * (lines[f, k + 1, 0] - lines[f, k - 1, 0]),
            0.5 * (lines[f, k + 1, 1] - lines[f, k - 1, 1]))
