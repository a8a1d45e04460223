"""The world's run: every step of a tool path in one compiled loop."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .consts import (FORCE_TOL, I_ADH, I_ADH_RANGE, I_CN, I_EI, I_GRAV, I_KC, I_KT, I_LET_GO,
                     I_MU_MOULD, I_MU_TOOL, I_SWEEP, JIT, MAX_NEWTON, TOOL)
from .obstacles import contact_scale, obstacle_gap
from .links import link_affine, link_constants, link_update, pb_factor, pb_solve
from .assemble import add_contact, assemble


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
    grav = np.zeros(n)
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
        # (along the sheet from |I_SWEEP| i / (N - 1) on when the hands sweep off it)
        for i in range(n):
            frac = (i if par[I_SWEEP] > 0.0 else n - 1 - i) / max(n - 1, 1)
            since = t1 - abs(par[I_SWEEP]) * frac
            grav[i] = par[I_GRAV] * (min(1.0, max(since, 0.0) / par[I_LET_GO])
                                     if par[I_LET_GO] > 0.0 else (1.0 if since >= 0.0 else 0.0))
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
                            soft = contact_scale(par, o)
                            if -kc / soft * (g0[i, o] + dn) - cn / math.sqrt(soft) * vn < 0.0:
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
                soft = contact_scale(par, o)
                kt_o = kt / soft
                fn = -kc / soft * gap - cn / math.sqrt(soft) * (nx * (v[i, 0] - ovel[o, 0])
                                                                + nz * (v[i, 1] - ovel[o, 1]))
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
                    if kt_o * abs(s) > cap:            # slip: the anchor follows
                        sg = 1.0 if s > 0.0 else -1.0
                        shift = s - sg * cap / kt_o
                        anc[i, o, 0] += shift * sx
                        anc[i, o, 1] += shift * sz
                        s = sg * cap / kt_o
                    fx -= kt_o * s * sx
                    fz -= kt_o * s * sz
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
