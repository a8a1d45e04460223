"""The dynamic world's compiled step (numba): a linearly implicit Euler step of a
chain of point masses with three-element links, soft penalty contact with
Coulomb friction (elastic-plastic anchors) and every effect of the world.

Written apart from :mod:`rheo_shaping.sheet.kernel` (no code in common): the
sheet model minimises an incremental potential by Newton to a quasi-static
equilibrium with a frictionless projection-like contact; this world takes one
linear solve per step of ~1 ms, with inertia, air damping, a soft contact of
finite stiffness and damping, and friction that sticks and slips.

One step of length ``h`` [s] (Baraff-Witkin form, positions ``x`` [m], velocities
``v`` [m/s], mass matrix ``M``):

    (M/h^2 + K + D/h) delta = M v/h + f(x),     x' = x + delta,  v' = delta/h

with ``f`` every force at the step's start (the obstacles at their END pose),
``K`` the positive semi-definite part of -df/dx (link axial and geometric
stiffness, contact normal and stick stiffness, bending) and ``D`` the damping
(air, contact).  ``K`` is banded: half bandwidth 3 in the x, z unknowns (5 with
bending); a banded Cholesky factor of our own solves it.

The link law (paper Eq. 2, k1 || c1 in series with c2) is integrated by the
backward Euler rule over the step, given the link's end length ``l'``:

    e1' = ((c1 + c2) e1 + c2 D) / (c1 + c2 + k1 h),   D = l' - (L0 + e1 + p)
    F'  = k1 e1' + c1 (e1' - e1)/h,                   p' = p + D - (e1' - e1)

(affine in ``l'``: F' = A + S D), slack (F' < 0): F' = 0, p' = p,
e1' = c1 e1/(c1 + k1 h).  First order in h: 1e-4 of the force at h = 1 ms for the
paper's Maxwell constants (Eq. 5, 7-8 in test/worlds).
"""
from __future__ import annotations

import math
from typing import Literal, TypedDict

import numpy as np
from numba import njit


class JitOptions(TypedDict):
    """The numba options of every compiled function of this world (``@njit(**JIT)``)."""

    cache: bool
    nogil: bool
    fastmath: bool
    error_model: Literal["python", "numpy"]


JIT: JitOptions = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")

# ---------------------------------------------------------------- packed parameter indices
#: ``par`` vector of :func:`run_chain`
(I_GRAV, I_KC, I_CN, I_KT, I_MU_MOULD, I_MU_TOOL, I_AIR, I_CAKE_H, I_FILLET, I_RADIUS,
 I_TOOL_R, I_EI, I_PL_N, I_PL_REF, I_THIN, I_HARD, I_ADH, I_ADH_RANGE, I_LET_GO) = range(19)
N_PAR = 19
#: obstacles
CAKE, FLOOR, TOOL = 0, 1, 2
#: Newton solves per step at most, and the link-force mismatch [N] (law against its linear
#: model at the solution) below which a step is converged
MAX_NEWTON = 6
FORCE_TOL = 1e-4


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


# ---------------------------------------------------------------- links (paper Eq. 2)
@njit(**JIT)
def link_affine(k1, c1, c2, e1, h):
    """(A, S): the backward-Euler link force F' = A + S D [N] over a step ``h`` [s], D [m] the
    end length beyond the free length L0 + e1 + p (Eq. 2 discretised)."""
    den = c1 + c2 + k1 * h
    g = k1 + c1 / h
    S = g * c2 / den
    A = g * (c1 + c2) * e1 / den - c1 / h * e1
    return A, S


@njit(**JIT)
def link_update(k1, c1, c2, e1, p, D, h):
    """(e1', p', F') of one link after a step ``h`` whose end length is D beyond the free
    length; slack (F' < 0): no force, no flow, the Kelvin part relaxes."""
    den = c1 + c2 + k1 * h
    e1n = ((c1 + c2) * e1 + c2 * D) / den
    F = k1 * e1n + c1 * (e1n - e1) / h
    if F >= 0.0:
        return e1n, p + D - (e1n - e1), F
    return c1 * e1 / (c1 + k1 * h), p, 0.0


@njit(**JIT)
def link_constants(L0, k1, c1, c2, e1, p, tension, par, out):
    """k1, c1, c2 of every link over this step, lagged on the state: thinning (L0/(L0+p))^b,
    power-law c2 (F/F_ref)^(1-1/n), strain hardening k1 (1 + beta (l - L0)/L0)."""
    b = par[I_THIN]
    n = par[I_PL_N]
    ref = par[I_PL_REF]
    beta = par[I_HARD]
    for i in range(L0.size):
        s = 1.0
        if b > 0.0 and p[i] > 0.0:
            s = (L0[i] / (L0[i] + p[i])) ** b
        kk = k1[i] * s
        if beta != 0.0:
            strain = (e1[i] + p[i]) / L0[i]
            kk *= 1.0 + beta * max(strain, 0.0)
        cc2 = c2[i] * s
        if n != 1.0:
            F = max(tension[i], 1e-3 * ref)
            cc2 *= (F / ref) ** (1.0 - 1.0 / n)
        out[0, i] = kk
        out[1, i] = c1[i] * s
        out[2, i] = cc2


# ---------------------------------------------------------------- banded SPD solve
@njit(**JIT)
def pb_factor(ab, kd):
    """In-place Cholesky of an SPD band matrix in LAPACK lower storage ``ab[d, j] = A[j + d,
    j]`` (d <= kd); False when not positive definite."""
    n = ab.shape[1]
    for j in range(n):
        lo = max(0, j - kd)
        acc = ab[0, j]
        for k in range(lo, j):
            acc -= ab[j - k, k] ** 2
        if acc <= 0.0:
            return False
        djj = math.sqrt(acc)
        ab[0, j] = djj
        for i in range(j + 1, min(n, j + kd + 1)):
            acc = ab[i - j, j]
            for k in range(max(0, i - kd), j):
                acc -= ab[i - k, k] * ab[j - k, k]
            ab[i - j, j] = acc / djj
    return True


@njit(**JIT)
def pb_solve(ab, kd, rhs):
    """Solve with the factor of :func:`pb_factor`, ``rhs`` overwritten by the solution."""
    n = ab.shape[1]
    for j in range(n):
        acc = rhs[j]
        for k in range(max(0, j - kd), j):
            acc -= ab[j - k, k] * rhs[k]
        rhs[j] = acc / ab[0, j]
    for j in range(n - 1, -1, -1):
        acc = rhs[j]
        for i in range(j + 1, min(n, j + kd + 1)):
            acc -= ab[i - j, j] * rhs[i]
        rhs[j] = acc / ab[0, j]


@njit(**JIT)
def add_block(ab, a, b, kxx, kxz, kzz):
    """Add the symmetric 2x2 block [[kxx, kxz], [kxz, kzz]] at masses (a, b) (a >= b) of the
    band; a negative index (a bond) adds nothing."""
    if a < 0 or b < 0:
        return
    ra = 2 * a
    rb = 2 * b
    if a == b:
        ab[0, ra] += kxx
        ab[1, ra] += kxz
        ab[0, ra + 1] += kzz
    else:
        ab[ra - rb, rb] += kxx
        ab[ra - rb + 1, rb] += kxz          # row ra+1 (z of a), column rb (x of b)
        ab[ra - rb - 1, rb + 1] += kxz      # row ra (x of a), column rb+1 (z of b)
        ab[ra - rb, rb + 1] += kzz


@njit(**JIT)
def add_contact(ab, rhs, i, o, xk, dlt, x, g0, n0, ovel, opos, anc, has, par, h, fad):
    """Add the contact of mass ``i`` on obstacle ``o`` at the iterate ``xk`` = ``x`` +
    ``dlt`` to the step's Newton system: the penalty kc (-gap) along the normal
    (linearised, so a contact that starts this step acts), the normal damping cn on the
    velocity dlt/h relative to the obstacle, and Coulomb friction: a stick spring kt to an
    anchor fixed on the obstacle while kt |s| <= mu F_n + fad, else the slip force
    mu F_n + fad (``fad`` [N]: a sticky mould's shear strength at this mass, 0 on the
    tool)."""
    kc = par[I_KC]
    cn = par[I_CN]
    nx = n0[i, o, 0]
    nz = n0[i, o, 1]
    gap = g0[i, o]
    rhs[2 * i] -= kc * gap * nx
    rhs[2 * i + 1] -= kc * gap * nz
    add_block(ab, i, i, kc * nx * nx, kc * nx * nz, kc * nz * nz)
    vn = (nx * dlt[i, 0] + nz * dlt[i, 1]) / h - (nx * ovel[o, 0] + nz * ovel[o, 1])
    rhs[2 * i] -= cn * vn * nx
    rhs[2 * i + 1] -= cn * vn * nz
    add_block(ab, i, i, cn / h * nx * nx, cn / h * nx * nz, cn / h * nz * nz)
    mu = par[I_MU_TOOL] if o == TOOL else par[I_MU_MOULD]
    if mu <= 0.0 and fad <= 0.0:
        return
    if not has[i, o]:
        anc[i, o, 0] = x[i, 0] - opos[o, 0]
        anc[i, o, 1] = x[i, 1] - opos[o, 1]
        has[i, o] = True
    kt = par[I_KT]
    sx = -nz
    sz = nx
    s = sx * (xk[i, 0] - opos[o, 0] - anc[i, o, 0]) + sz * (xk[i, 1] - opos[o, 1] - anc[i, o, 1])
    cap = mu * max(-kc * gap, 0.0) + fad
    if kt * abs(s) <= cap:
        rhs[2 * i] -= kt * s * sx
        rhs[2 * i + 1] -= kt * s * sz
        add_block(ab, i, i, kt * sx * sx, kt * sx * sz, kt * sz * sz)
    else:
        sg = 1.0 if s > 0.0 else -1.0
        rhs[2 * i] -= cap * sg * sx
        rhs[2 * i + 1] -= cap * sg * sz


@njit(**JIT)
def assemble(ab, rhs, xk, dlt, v, mass, nodes, L0, consts, free, A, S, taut, bend_n, kb,
             fadh, par, h, first, grav):
    """The step's Newton system at the iterate ``xk`` (= x + ``dlt``) without the contacts:
    rhs = -R with R = M (dlt - h v)/h^2 + air M dlt/h - f(xk) (gravity ``grav``, links at their
    end-of-step law F = A + S (l - free), bending on the step-start normals ``bend_n``,
    adhesion ``fadh``), ``ab`` = dR/d(dlt) in band form.  On the ``first`` iterate a link
    is taut if it is now or would be at the predicted length, later if it is now."""
    n = xk.shape[0]
    m = n + 1
    air = par[I_AIR]
    ab[:, :] = 0.0
    for i in range(n):
        mi = mass[i]
        diag = mi / (h * h) + air * mi / h
        ab[0, 2 * i] += diag
        ab[0, 2 * i + 1] += diag
        for c in range(2):
            rhs[2 * i + c] = -mi * (dlt[i, c] - h * v[i, c]) / (h * h) - air * mi * dlt[i, c] / h \
                + fadh[i, c]
        rhs[2 * i + 1] -= mi * grav
    nodes[1:n + 1] = xk
    for i in range(m):
        a, b = i - 1, i                          # mass indices of the link's ends
        dx = nodes[i + 1, 0] - nodes[i, 0]
        dz = nodes[i + 1, 1] - nodes[i, 1]
        ln = math.sqrt(dx * dx + dz * dz)
        ux = dx / ln
        uz = dz / ln
        F = A[i] + S[i] * (ln - free[i])
        if first:
            pvx = (v[b, 0] if b < n else 0.0) - (v[a, 0] if a >= 0 else 0.0)
            pvz = (v[b, 1] if b < n else 0.0) - (v[a, 1] if a >= 0 else 0.0)
            lp = math.sqrt((dx + h * pvx) ** 2 + (dz + h * pvz) ** 2)
            taut[i] = F > 0.0 or A[i] + S[i] * (lp - free[i]) > 0.0
        else:
            taut[i] = F > 0.0
        if not taut[i]:
            continue
        Si = S[i]
        if a >= 0:
            rhs[2 * a] += F * ux
            rhs[2 * a + 1] += F * uz
        if b < n:
            rhs[2 * b] -= F * ux
            rhs[2 * b + 1] -= F * uz
        g = max(F, 0.0) / ln
        kxx = Si * ux * ux + g * (1.0 - ux * ux)
        kxz = (Si - g) * ux * uz
        kzz = Si * uz * uz + g * (1.0 - uz * uz)
        if a >= 0:
            add_block(ab, a, a, kxx, kxz, kzz)
        if b < n:
            add_block(ab, b, b, kxx, kxz, kzz)
        if a >= 0 and b < n:
            add_block(ab, b, a, -kxx, -kxz, -kzz)
    if par[I_EI] > 0.0:
        # bending: E = kb/2 (n . (x_{j-1} - 2 x_j + x_{j+1}))^2 per mass, kb = EI / h^3
        for i in range(n):
            j = i + 1                                # node index
            nx = bend_n[i, 0]
            nz = bend_n[i, 1]
            bval = nx * (nodes[j - 1, 0] - 2 * nodes[j, 0] + nodes[j + 1, 0]) + \
                nz * (nodes[j - 1, 1] - 2 * nodes[j, 1] + nodes[j + 1, 1])
            k = kb[i]
            for (ma, ca) in ((i - 1, 1.0), (i, -2.0), (i + 1, 1.0)):
                if not 0 <= ma < n:
                    continue
                rhs[2 * ma] -= k * bval * ca * nx
                rhs[2 * ma + 1] -= k * bval * ca * nz
                for (mb, cb) in ((i - 1, 1.0), (i, -2.0), (i + 1, 1.0)):
                    if 0 <= mb <= ma:
                        f = k * ca * cb
                        add_block(ab, ma, mb, f * nx * nx, f * nx * nz, f * nz * nz)


# ---------------------------------------------------------------- the run
@njit(**JIT)
def run_chain(x, v, anchors, L0, k1, c1, c2, mass, par, verts, tool_t, tool_xz, hs, keep,
              e1, p):
    """Steps of ``hs`` (S,) [s] from t = 0; the tool (reference point at ``tool_xz`` (T, 2)
    [m], sampled at ``tool_t`` (T,) [s], the real pose incl. any offset) interpolated
    linearly.  ``x``, ``v`` (N, 2), ``e1``, ``p`` (N+1,) are advanced in place; ``anchors``
    (2, 2) are the bonds.  After each step with ``keep`` (S,) true a sample is kept:
    positions, plastic elongation, the time means of link tension and tool force since the
    last sample.

    Each step solves the backward-Euler equations by Newton's method (at most
    ``MAX_NEWTON`` solves; it stops when no link's law is off its linear model by more
    than ``FORCE_TOL`` and the contact set holds), each solve on an active set of
    contacts (a contact that would pull is let go, one that would be passed through is
    held).

    Returns (t (K,), x (K, N, 2), tension (K, N+1), tool force (K, 2) of the sheet on the
    tool [N], plastic (K, N+1), mould force (K, 2) [N], status: 0 ok, 1 not positive
    definite, 2 non-finite, steps that used every Newton solve without converging)."""
    n = x.shape[0]
    m = n + 1
    n_steps = hs.size
    n_out = int(keep.sum()) + 1
    kd = 5 if par[I_EI] > 0.0 else 3
    ndof = 2 * n
    out_t = np.zeros(n_out)
    out_x = np.zeros((n_out, n, 2))
    out_F = np.zeros((n_out, m))
    out_tool = np.zeros((n_out, 2))
    out_p = np.zeros((n_out, m))
    out_mould = np.zeros((n_out, 2))
    ab = np.zeros((kd + 1, ndof))
    ab0 = np.zeros((kd + 1, ndof))
    rhs = np.zeros(ndof)
    rhs0 = np.zeros(ndof)
    consts = np.zeros((3, m))
    tension = np.zeros(m)
    A = np.zeros(m)
    S = np.zeros(m)
    free = np.zeros(m)
    taut = np.zeros(m, dtype=np.bool_)
    anc = np.zeros((n, 3, 2))      # friction anchors per mass and obstacle (tool: its frame)
    has = np.zeros((n, 3), dtype=np.bool_)
    g0 = np.zeros((n, 3))
    n0 = np.zeros((n, 3, 2))
    act = np.zeros((n, 3), dtype=np.bool_)
    ovel = np.zeros((3, 2))        # obstacles' velocity and position (only the tool moves)
    opos = np.zeros((3, 2))
    fsum_F = np.zeros(m)
    fsum_tool = np.zeros(2)
    fsum_mould = np.zeros(2)
    nodes = np.zeros((n + 2, 2))
    nodes[0] = anchors[0]
    nodes[n + 1] = anchors[1]
    dlt = np.zeros((n, 2))
    xk = np.zeros((n, 2))
    fadh = np.zeros((n, 2))
    bend_n = np.zeros((n, 2))
    kc = par[I_KC]
    cn = par[I_CN]
    kt = par[I_KT]
    adh = par[I_ADH]
    adh_rng = par[I_ADH_RANGE]
    kb = np.zeros(n)
    for i in range(n):
        kb[i] = par[I_EI] / (0.5 * (L0[i] + L0[i + 1])) ** 3
    out_x[0] = x
    out_p[0] = p
    k_out = 1
    ti = 0
    tx0, tz0 = tool_xz[0, 0], tool_xz[0, 1]
    t1 = 0.0
    span = 0.0
    n_unconv = 0
    for step in range(n_steps):
        h = hs[step]
        t1 += h
        span += h
        while ti < tool_t.size - 2 and tool_t[ti + 1] < t1:
            ti += 1
        w = min(max((t1 - tool_t[ti]) / (tool_t[ti + 1] - tool_t[ti]), 0.0), 1.0)
        tx = tool_xz[ti, 0] + w * (tool_xz[ti + 1, 0] - tool_xz[ti, 0])
        tz = tool_xz[ti, 1] + w * (tool_xz[ti + 1, 1] - tool_xz[ti, 1])
        ovel[TOOL, 0] = (tx - tx0) / h
        ovel[TOOL, 1] = (tz - tz0) / h
        opos[TOOL, 0] = tx
        opos[TOOL, 1] = tz
        # the hands let go: the sheet's weight comes on over par[I_LET_GO] seconds
        grav = par[I_GRAV] * (min(1.0, t1 / par[I_LET_GO]) if par[I_LET_GO] > 0.0 else 1.0)
        # the links' law over this step (constants lagged on the state), bending normals,
        # adhesion: all from the step's start
        link_constants(L0, k1, c1, c2, e1, p, tension, par, consts)
        for i in range(m):
            free[i] = L0[i] + e1[i] + p[i]
            A[i], S[i] = link_affine(consts[0, i], consts[1, i], consts[2, i], e1[i], h)
        nodes[1:n + 1] = x
        for i in range(n):
            qx = nodes[i + 2, 0] - nodes[i, 0]
            qz = nodes[i + 2, 1] - nodes[i, 1]
            lq = math.sqrt(qx * qx + qz * qz)
            bend_n[i, 0] = -qz / lq
            bend_n[i, 1] = qx / lq
            fadh[i, 0] = 0.0
            fadh[i, 1] = 0.0
            if adh > 0.0:
                for o in range(2):
                    gap, nx, nz = obstacle_gap(o, x[i, 0], x[i, 1], par, verts, tx, tz)
                    if gap < adh_rng:
                        fa = adh * 0.5 * (L0[i] + L0[i + 1]) * (1.0 - max(gap, 0.0) / adh_rng)
                        fadh[i, 0] -= fa * nx
                        fadh[i, 1] -= fa * nz
        dlt[:, :] = 0.0
        for newton in range(MAX_NEWTON):
            for i in range(n):
                xk[i, 0] = x[i, 0] + dlt[i, 0]
                xk[i, 1] = x[i, 1] + dlt[i, 1]
            assemble(ab0, rhs0, xk, dlt, v, mass, nodes, L0, consts, free, A, S, taut,
                     bend_n, kb, fadh, par, h, newton == 0, grav)
            for i in range(n):
                for o in range(3):
                    gap, nx, nz = obstacle_gap(o, xk[i, 0], xk[i, 1], par, verts, tx, tz)
                    g0[i, o] = gap
                    n0[i, o, 0] = nx
                    n0[i, o, 1] = nz
                    if newton == 0:         # later solves start from the last active set
                        vrel = nx * (v[i, 0] - ovel[o, 0]) + nz * (v[i, 1] - ovel[o, 1])
                        act[i, o] = gap < 0.0 or gap + h * vrel < 0.0
            set_changed = False
            for _it in range(4):
                ab[:, :] = ab0
                rhs[:] = rhs0
                for i in range(n):
                    for o in range(3):
                        if act[i, o]:
                            fad = 0.0 if o == TOOL else adh * 0.5 * (L0[i] + L0[i + 1])
                            add_contact(ab, rhs, i, o, xk, dlt, x, g0, n0, ovel, opos, anc,
                                        has, par, h, fad)
                if not pb_factor(ab, kd):
                    return out_t[:k_out], out_x[:k_out], out_F[:k_out], out_tool[:k_out], \
                        out_p[:k_out], out_mould[:k_out], 1, n_unconv
                pb_solve(ab, kd, rhs)
                changed = False
                for i in range(n):
                    for o in range(3):
                        nx = n0[i, o, 0]
                        nz = n0[i, o, 1]
                        dn = nx * rhs[2 * i] + nz * rhs[2 * i + 1]
                        if act[i, o]:
                            vn = (nx * (dlt[i, 0] + rhs[2 * i]) + nz * (dlt[i, 1] + rhs[2 * i + 1])
                                  ) / h - (nx * ovel[o, 0] + nz * ovel[o, 1])
                            if -kc * (g0[i, o] + dn) - cn * vn < 0.0:
                                act[i, o] = False           # it would pull: let go
                                changed = True
                        elif g0[i, o] + dn < 0.0:
                            act[i, o] = True                # it would pass through: hold it
                            changed = True
                if not changed:
                    break
                set_changed = True
            # the Newton update; converged when every taut link's law is on its linear model
            worst = 0.0
            for i in range(n):
                dlt[i, 0] += rhs[2 * i]
                dlt[i, 1] += rhs[2 * i + 1]
            for i in range(m):
                if not taut[i]:
                    continue
                a, b = i - 1, i
                dax = rhs[2 * a] if a >= 0 else 0.0
                daz = rhs[2 * a + 1] if a >= 0 else 0.0
                dbx = rhs[2 * b] if b < n else 0.0
                dbz = rhs[2 * b + 1] if b < n else 0.0
                ax = nodes[i, 0] + (dax if a >= 0 else 0.0)
                az = nodes[i, 1] + (daz if a >= 0 else 0.0)
                bx = nodes[i + 1, 0] + (dbx if b < n else 0.0)
                bz = nodes[i + 1, 1] + (dbz if b < n else 0.0)
                l_old = math.sqrt((nodes[i + 1, 0] - nodes[i, 0]) ** 2
                                  + (nodes[i + 1, 1] - nodes[i, 1]) ** 2)
                ux = (nodes[i + 1, 0] - nodes[i, 0]) / l_old
                uz = (nodes[i + 1, 1] - nodes[i, 1]) / l_old
                l_lin = l_old + ux * (dbx - dax) + uz * (dbz - daz)
                l_new = math.sqrt((bx - ax) ** 2 + (bz - az) ** 2)
                worst = max(worst, S[i] * abs(l_new - l_lin))
            if worst < FORCE_TOL and not set_changed:
                break
            if newton == MAX_NEWTON - 1:
                n_unconv += 1
        for i in range(n):
            v[i, 0] = dlt[i, 0] / h
            v[i, 1] = dlt[i, 1] / h
            x[i, 0] += dlt[i, 0]
            x[i, 1] += dlt[i, 1]
        if not np.all(np.isfinite(x)):
            return out_t[:k_out], out_x[:k_out], out_F[:k_out], out_tool[:k_out], \
                out_p[:k_out], out_mould[:k_out], 2, n_unconv
        # the links' state at the step's end
        nodes[1:n + 1] = x
        for i in range(m):
            dx = nodes[i + 1, 0] - nodes[i, 0]
            dz = nodes[i + 1, 1] - nodes[i, 1]
            ln = math.sqrt(dx * dx + dz * dz)
            e1n, pn, F = link_update(consts[0, i], consts[1, i], consts[2, i], e1[i], p[i],
                                     ln - free[i], h)
            e1[i] = e1n
            p[i] = pn
            tension[i] = F
            fsum_F[i] += F * h
        # contact forces at the step's end (the load cell, the mould) and the anchors' slip
        for i in range(n):
            for o in range(3):
                gap, nx, nz = obstacle_gap(o, x[i, 0], x[i, 1], par, verts, tx, tz)
                if gap >= 0.0:
                    has[i, o] = False
                    continue
                fn = -kc * gap - cn * (nx * (v[i, 0] - ovel[o, 0]) + nz * (v[i, 1] - ovel[o, 1]))
                fn = max(fn, 0.0)
                fx = fn * nx
                fz = fn * nz
                mu = par[I_MU_TOOL] if o == TOOL else par[I_MU_MOULD]
                if has[i, o]:
                    sx = -nz
                    sz = nx
                    s = sx * (x[i, 0] - opos[o, 0] - anc[i, o, 0]) + \
                        sz * (x[i, 1] - opos[o, 1] - anc[i, o, 1])
                    cap = mu * fn + (0.0 if o == TOOL else adh * 0.5 * (L0[i] + L0[i + 1]))
                    if kt * abs(s) > cap:              # slip: the anchor follows
                        sg = 1.0 if s > 0.0 else -1.0
                        shift = s - sg * cap / kt
                        anc[i, o, 0] += shift * sx
                        anc[i, o, 1] += shift * sz
                        s = sg * cap / kt
                    fx -= kt * s * sx
                    fz -= kt * s * sz
                if o == TOOL:
                    fsum_tool[0] -= fx * h
                    fsum_tool[1] -= fz * h
                else:
                    fsum_mould[0] -= fx * h
                    fsum_mould[1] -= fz * h
        tx0, tz0 = tx, tz
        if keep[step] and k_out < n_out:
            out_t[k_out] = t1
            out_x[k_out] = x
            out_p[k_out] = p
            for i in range(m):
                out_F[k_out, i] = fsum_F[i] / span
                fsum_F[i] = 0.0
            for c in range(2):
                out_tool[k_out, c] = fsum_tool[c] / span
                out_mould[k_out, c] = fsum_mould[c] / span
                fsum_tool[c] = 0.0
                fsum_mould[c] = 0.0
            k_out += 1
            span = 0.0
    return out_t[:k_out], out_x[:k_out], out_F[:k_out], out_tool[:k_out], out_p[:k_out], \
        out_mould[:k_out], 0, n_unconv
