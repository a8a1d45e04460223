"""Signed distance, normal and curvature of the obstacle shapes (compiled)."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .consts import CAKE_KIND, JIT, PLANE_KIND, TINY


# ------------------------------------------------------------------------ geometry
@njit(**JIT)
def shape_eval(kind, nv, verts, rad, px, pz, ox, oz):
    """Signed distance d [m], outward normal (nx, nz) and curvature kappa [1/m] of the
    distance's level set at point (px, pz) of a shape translated by (ox, oz).

    Cake (kind 0): the quadrant x <= cx, z <= cz (``verts[0, :2]``) grown by ``rad``;
    plane (1): z <= 0; polygon (2): convex polygon of ``nv`` vertices (CCW) grown by
    ``rad`` (nv = 1 a disc, 2 a capsule), ``verts`` its :func:`shape_table`.  kappa is
    1/(d + rad) where the nearest feature is a corner point, 0 along a flat face and inside.
    """
    if kind == PLANE_KIND:
        return pz - oz, 0.0, 1.0, 0.0
    if kind == CAKE_KIND:
        qx = px - (verts[0, 0] + ox)
        qz = pz - (verts[0, 1] + oz)
        qpx = qx if qx > 0.0 else 0.0
        qpz = qz if qz > 0.0 else 0.0
        dist = math.sqrt(qpx * qpx + qpz * qpz)
        if dist > 0.0:
            kap = 1.0 / dist if (qpx > 0.0 and qpz > 0.0) else 0.0
            return dist - rad, qpx / dist, qpz / dist, kap
        if qx >= qz:
            return qx - rad, 1.0, 0.0, 0.0
        return qz - rad, 0.0, 1.0, 0.0
    # rounded convex polygon
    rx0 = px - ox
    rz0 = pz - oz
    if nv == 1:
        rx = rx0 - verts[0, 0]
        rz = rz0 - verts[0, 1]
        dist = math.sqrt(rx * rx + rz * rz)
        if dist > 0.0:
            return dist - rad, rx / dist, rz / dist, 1.0 / dist
        return dist - rad, 0.0, 1.0, 0.0
    best = np.inf
    bdx = 0.0
    bdz = 0.0
    bt = 0.0
    smax = -np.inf
    snx = 0.0
    snz = 0.0
    for j in range(nv):
        # table row: vertex, edge to the next vertex, 1/|edge|^2, outward edge normal
        rx = rx0 - verts[j, 0]
        rz = rz0 - verts[j, 1]
        ex = verts[j, 2]
        ez = verts[j, 3]
        t = (rx * ex + rz * ez) * verts[j, 4]
        t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        dx = rx - t * ex
        dz = rz - t * ez
        d2 = dx * dx + dz * dz
        if d2 < best:
            best = d2
            bdx = dx
            bdz = dz
            bt = t
        s = rx * verts[j, 5] + rz * verts[j, 6]
        if s > smax:
            smax = s
            snx = verts[j, 5]
            snz = verts[j, 6]
    dist = math.sqrt(best)
    dd = dist if dist > TINY else TINY
    kap = 1.0 / dd if (bt <= 0.0 or bt >= 1.0) else 0.0
    if nv == 2:                                     # capsule: no interior
        if dist > 0.0:
            return dist - rad, bdx / dd, bdz / dd, kap
        return dist - rad, verts[0, 5], verts[0, 6], 0.0
    if smax > 0.0:
        return dist - rad, bdx / dd, bdz / dd, kap
    return smax - rad, snx, snz, 0.0


@njit(**JIT)
def shape_eval_many(kind, nv, verts, rad, pts, ox, oz):
    """:func:`shape_eval` over points (M, 2): d (M,), n (M, 2), kappa (M,)."""
    m = pts.shape[0]
    d = np.empty(m)
    n = np.empty((m, 2))
    kap = np.empty(m)
    for i in range(m):
        d[i], n[i, 0], n[i, 1], kap[i] = shape_eval(kind, nv, verts, rad, pts[i, 0], pts[i, 1],
                                                    ox, oz)
    return d, n, kap
