"""The arrays the compiled step takes, packed from the model (plain Python)."""
from __future__ import annotations

import numpy as np

from .consts import (P_BENDING, P_BOTX, P_BOTZ, P_EPS, P_GRAVITY, P_KC, P_PLN, P_PLREF, P_RADIUS,
                     P_SHX, P_SHZ, P_SIZE, P_THIN, P_TOL, P_TOPX, P_TOPZ)


def shape_table(verts) -> np.ndarray:
    """Rows (K, 8) of a shape's vertices (K, 2) [m]: vertex x, z, edge to the next vertex
    x, z, 1/|edge|^2 [1/m^2] (0 for a single vertex), outward unit edge normal x, z, 0."""
    v = np.asarray(verts, dtype=float).reshape(-1, 2)
    table = np.zeros((max(len(v), 1), 8))
    if len(v) == 0:
        return table
    e = np.roll(v, -1, axis=0) - v
    len2 = np.einsum("ij,ij->i", e, e)
    with np.errstate(divide="ignore"):
        inv = np.where(len2 > 0.0, 1.0 / np.where(len2 > 0, len2, 1.0), 0.0)
    ln = np.sqrt(len2)
    nrm = np.column_stack((e[:, 1], -e[:, 0])) / np.where(ln > 0, ln, 1.0)[:, None]
    table[:, 0:2], table[:, 2:4], table[:, 4], table[:, 5:7] = v, e, inv, nrm
    return table


#: What :func:`pack_model` returns: (fpar, links, masses, ob_i, ob_f, ob_v).
Packed = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def pack_model(constants, obstacles, reach, mu, kc: float, force_tol: float,
               effects) -> Packed:
    """The arrays the kernel takes: (fpar, links (5, N+1), masses (2, N), ob_i, ob_f, ob_v)."""
    c = constants
    n = c.n_masses
    fpar = np.zeros(P_SIZE)
    fpar[P_RADIUS] = c.radius
    fpar[P_GRAVITY] = c.gravity
    fpar[P_KC] = kc
    fpar[P_TOL] = force_tol
    fpar[P_THIN] = effects.thinning
    fpar[P_PLN] = effects.power_law_n
    fpar[P_PLREF] = effects.power_law_ref
    fpar[P_EPS] = effects.friction_slip
    fpar[P_SHX], fpar[P_SHZ] = effects.tool_shift
    fpar[P_TOPX], fpar[P_TOPZ] = c.anchor_top
    fpar[P_BOTX], fpar[P_BOTZ] = c.anchor_bottom
    fpar[P_BENDING] = effects.bending
    links = np.zeros((5, n + 1))
    links[0], links[1], links[2], links[3] = c.rest_length, c.k1, c.c1, c.c2
    masses = np.zeros((2, n))
    masses[0] = c.mass
    if effects.bending > 0.0:
        h = 0.5 * (c.rest_length[:-1] + c.rest_length[1:])
        masses[1] = effects.bending / h ** 3        # N/m per mass, EI / h^3
    descs = [ob.shape.kernel_description() for ob in obstacles]
    kmax = max([len(d[2]) for d in descs] + [1])
    ob_i = np.zeros((len(obstacles), 3), dtype=np.int64)
    ob_f = np.zeros((len(obstacles), 3))
    ob_v = np.zeros((len(obstacles), kmax, 8))
    for k, (ob, (kind, rad, verts)) in enumerate(zip(obstacles, descs)):
        ob_i[k] = (kind, len(verts), 1 if ob.moving else 0)
        ob_f[k] = (rad, reach[k], mu[k])
        if len(verts):
            ob_v[k, :len(verts)] = shape_table(verts)
    return fpar, links, masses, ob_i, ob_f, ob_v
