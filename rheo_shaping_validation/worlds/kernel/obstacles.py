"""Obstacles of the world: signed gaps and normals to cake, workplane and the tool's
rounded polygon, and the laid sheet pushed out of them."""
from __future__ import annotations

import math

from numba import njit

from .consts import (CAKE, FLOOR, I_CAKE_H, I_FILLET, I_RADIUS, I_SOFT_MOULD, I_SOFT_TOOL,
                     I_TOOL_R, JIT, TOOL)


# ---------------------------------------------------------------- obstacles
@njit(**JIT)
def cake_gap(px, pz, height, fillet):
    """Signed distance [m] of (px, pz) to the cake x <= 0, z <= height with a rounded top
    edge of radius ``fillet``, and the outward normal (nx, nz)."""
    cx = -fillet
    cz = height - fillet
    if px > cx and pz > cz:                  # round the edge
        dx = px - cx
        dz = pz - cz
        r = math.sqrt(dx * dx + dz * dz)
        if r > 1e-15:
            return r - fillet, dx / r, dz / r
        return -fillet, 0.0, 1.0
    if px > cx:                              # beside the wall
        return px, 1.0, 0.0
    if pz > cz:                              # above the top face
        return pz - height, 0.0, 1.0
    if px > pz - height:                     # deep inside: the nearer face
        return px, 1.0, 0.0
    return pz - height, 0.0, 1.0


@njit(**JIT)
def polygon_gap(px, pz, verts, radius):
    """Signed distance [m] of (px, pz) to a convex polygon ``verts`` (K, 2) (CCW) grown by
    ``radius`` [m], and its outward normal; K = 1 is a disc."""
    k = verts.shape[0]
    if k == 1:
        dx = px - verts[0, 0]
        dz = pz - verts[0, 1]
        r = math.sqrt(dx * dx + dz * dz)
        if r < 1e-15:
            return -radius, 0.0, 1.0
        return r - radius, dx / r, dz / r
    # one pass over the edges: the largest edge-line distance (inside: that edge) and the
    # nearest boundary point (outside)
    best_line = -1e300
    bnx = 0.0
    bnz = 1.0
    dmin = 1e300
    qx = 0.0
    qz = 0.0
    for i in range(k):
        j = (i + 1) % k
        ex = verts[j, 0] - verts[i, 0]
        ez = verts[j, 1] - verts[i, 1]
        le2 = ex * ex + ez * ez
        le = math.sqrt(le2)
        rx = px - verts[i, 0]
        rz = pz - verts[i, 1]
        s = (rx * ez - rz * ex) / le
        if s > best_line:
            best_line = s
            bnx = ez / le
            bnz = -ex / le
        w = min(max((rx * ex + rz * ez) / le2, 0.0), 1.0)
        d = (rx - w * ex) ** 2 + (rz - w * ez) ** 2
        if d < dmin:
            dmin = d
            qx = verts[i, 0] + w * ex
            qz = verts[i, 1] + w * ez
    if best_line <= 0.0:
        return best_line - radius, bnx, bnz
    d = math.sqrt(dmin)
    return d - radius, (px - qx) / d, (pz - qz) / d


@njit(**JIT)
def obstacle_gap(o, px, pz, par, verts, tx, tz):
    """(gap to the sphere's surface [m], nx, nz) of obstacle ``o``; the tool at (tx, tz)."""
    r = par[I_RADIUS]
    if o == CAKE:
        d, nx, nz = cake_gap(px, pz, par[I_CAKE_H], par[I_FILLET])
    elif o == FLOOR:
        d, nx, nz = pz, 0.0, 1.0
    else:
        d, nx, nz = polygon_gap(px - tx, pz - tz, verts, par[I_TOOL_R])
    return d - r, nx, nz


@njit(**JIT)
def push_out(pts, par, verts, tx, tz, with_tool):
    """``pts`` (M, 2) [m] moved out of cake, workplane and (``with_tool``) the tool at (tx, tz)
    to touching distance, in place (three passes, for corners); returns ``pts``."""
    n_obst = 3 if with_tool else 2
    for _ in range(3):
        for j in range(pts.shape[0]):
            for o in range(n_obst):
                g, nx, nz = obstacle_gap(o, pts[j, 0], pts[j, 1], par, verts, tx, tz)
                if g < 0.0:
                    pts[j, 0] -= g * nx
                    pts[j, 1] -= g * nz
    return pts


@njit(**JIT)
def contact_scale(par, o):
    """The factor (>= 1) obstacle ``o``'s contact is softer than the penalty ``I_KC`` by (its
    stiffness / f, damping / sqrt(f)); a packed 0 reads as 1 (not softened)."""
    f = par[I_SOFT_TOOL] if o == TOOL else par[I_SOFT_MOULD]
    return f if f > 0.0 else 1.0
