"""One step of the sheet (with half-step retries), many equal steps, a whole path."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .consts import (JIT, OK, P_BENDING, P_BOTX, P_BOTZ, P_EPS, P_GRAVITY, P_KC, P_RADIUS, P_SHX,
                     P_SHZ, P_TOPX, P_TOPZ, ST_FAILED, ST_SUBSTEPS)
from .shapes import shape_eval
from .links import link_constants, link_factors
from .newton import minimise


# ------------------------------------------------------------------------ the step
@njit(**JIT)
def friction_setup(x, contact, tool_prev, tool_real, ob_i, ob_f, ob_v):
    """Friction terms of a step, lagged on the state: (on (n_ob,), tangents (n_ob, N, 2),
    mu * normal force (n_ob, N) [N], obstacle shifts over the step (n_ob, 2) [m])."""
    n = x.shape[0]
    n_ob = ob_i.shape[0]
    on = np.zeros(n_ob, dtype=np.bool_)
    tang = np.zeros((n_ob, n, 2))
    mun = np.zeros((n_ob, n))
    move = np.zeros((n_ob, 2))
    for o in range(n_ob):
        mu = ob_f[o, 2]
        if mu <= 0.0:
            continue
        moving = ob_i[o, 2] == 1
        ox = 0.0
        oz = 0.0
        if moving:
            if not (np.isfinite(tool_prev[0]) and np.isfinite(tool_prev[1])
                    and np.isfinite(tool_real[0]) and np.isfinite(tool_real[1])):
                continue
            ox = tool_prev[0]
            oz = tool_prev[1]
        anyp = False
        for j in range(n):
            d, nx, nz, kap = shape_eval(ob_i[o, 0], ob_i[o, 1], ob_v[o], ob_f[o, 0],
                                        x[j, 0], x[j, 1], ox, oz)
            lam = contact[o, j, 0] * nx + contact[o, j, 1] * nz
            if lam > 0.0:
                anyp = True
                mun[o, j] = mu * lam
            tang[o, j, 0] = -nz
            tang[o, j, 1] = nx
        if not anyp:
            mun[o, :] = 0.0
            continue
        on[o] = True
        if moving:
            move[o, 0] = tool_real[0] - tool_prev[0]
            move[o, 1] = tool_real[1] - tool_prev[1]
    return on, tang, mun, move


@njit(**JIT)
def one_step(x0, v0, e10, p0, ten0, con0, tool_prev, tool, dt, dynamic, fpar, links, masses,
             ob_i, ob_f, ob_v, max_newton, stats):
    """One implicit step of ``dt`` [s], the tool ending at ``tool``.  Returns
    (x, v, e1, p, tension, contact, iterations, status, residual [N])."""
    n = x0.shape[0]
    n_ob = ob_i.shape[0]
    k1, c1, c2 = link_constants(links, e10, p0, ten0, fpar)
    m_links = n + 1
    S = np.empty(m_links)
    L_star = np.empty(m_links)
    free = np.empty(m_links)
    for i in range(m_links):
        r, eps, g = link_factors(k1[i], c1[i], c2[i], dt)
        F0 = k1[i] * r * eps * e10[i]
        S[i] = r * (k1[i] * r * g + c1[i] / dt)
        free[i] = links[0, i] + e10[i] + p0[i]
        L_star[i] = free[i] - F0 / S[i]
    mass = masses[0]
    kb = masses[1]
    inertia = mass / (dt * dt)
    weight = mass * fpar[P_GRAVITY]
    guess = x0 + dt * v0                # warm start: continue the last motion
    x_pred = guess if dynamic else x0
    real_prev = np.array((tool_prev[0] + fpar[P_SHX], tool_prev[1] + fpar[P_SHZ]))
    real = np.array((tool[0] + fpar[P_SHX], tool[1] + fpar[P_SHZ]))
    fr_on, fr_tang, fr_mun, fr_move = friction_setup(x0, con0, real_prev, real, ob_i, ob_f,
                                                     ob_v)
    kd = 4 if fpar[P_BENDING] > 0.0 else 3
    fset = np.zeros((n_ob, n), dtype=np.bool_)     # the state's contacts (warm start)
    for o in range(n_ob):
        for j in range(n):
            fset[o, j] = con0[o, j, 0] != 0.0 or con0[o, j, 1] != 0.0
    x, iters, status, res, gd, gn, present = minimise(
        guess, x_pred, inertia, S, L_star, weight, kb, fpar, ob_i, ob_f, ob_v, real,
        fr_on, fr_tang, fr_mun, x0, fr_move, kd, max_newton, fset, stats)
    if status != OK:
        stats[ST_FAILED] += 1
        return x, v0, e10, p0, ten0, con0, iters, status, res
    # the links' exact update over the step (material.elongation_step)
    F = np.empty(m_links)
    e1 = np.empty(m_links)
    p = np.empty(m_links)
    for i in range(m_links):
        ax = fpar[P_TOPX] if i == 0 else x[i - 1, 0]
        az = fpar[P_TOPZ] if i == 0 else x[i - 1, 1]
        bx = fpar[P_BOTX] if i == n else x[i, 0]
        bz = fpar[P_BOTZ] if i == n else x[i, 1]
        l = math.sqrt((bx - ax) ** 2 + (bz - az) ** 2)  # noqa: E741
        delta = l - free[i]
        r, eps, g = link_factors(k1[i], c1[i], c2[i], dt)
        e1_taut = eps * e10[i] + r * g * delta
        Fi = k1[i] * r * e1_taut + r * c1[i] * delta / dt
        if Fi > 0.0:
            F[i] = Fi
            e1[i] = e1_taut
            p[i] = p0[i] + delta - (e1_taut - e10[i])
        else:
            relax = math.exp(-k1[i] * dt / c1[i]) if c1[i] > 0.0 else 0.0
            F[i] = 0.0
            e1[i] = e10[i] * relax
            p[i] = p0[i]
    radius = fpar[P_RADIUS]
    kc = fpar[P_KC]
    contact = np.zeros((n_ob, n, 2))
    for o in range(n_ob):
        if not present[o]:
            continue
        for j in range(n):
            pen = radius - gd[o, j]
            if pen > 0.0:
                contact[o, j, 0] = kc * pen * gn[o, j, 0]
                contact[o, j, 1] = kc * pen * gn[o, j, 1]
    eps_f = fpar[P_EPS]
    for o in range(n_ob):
        if not fr_on[o]:
            continue
        for j in range(n):
            tx = fr_tang[o, j, 0]
            tz = fr_tang[o, j, 1]
            u = (x[j, 0] - x0[j, 0] - fr_move[o, 0]) * tx \
                + (x[j, 1] - x0[j, 1] - fr_move[o, 1]) * tz
            fs = fr_mun[o, j] * u / math.sqrt(u * u + eps_f * eps_f)
            contact[o, j, 0] -= fs * tx
            contact[o, j, 1] -= fs * tz
    v = (x - x0) / dt   # quasi-static: only the warm start of the next step uses it
    return x, v, e1, p, F, contact, iters, OK, res


@njit(**JIT)
def advance(x, v, e1, p, ten, con, tool_prev, tool, dt, dynamic, min_dt, fpar, links, masses,
            ob_i, ob_f, ob_v, max_newton, stats):
    """Step of ``dt`` [s] from the state, the tool moving to ``tool``; a step whose Newton
    iteration fails is retried as two half steps (tool linear between its poses) down
    to ``min_dt``.  Returns (x, v, e1, p, tension, contact, tool, iterations, status,
    residual [N])."""
    cap = 64
    st_dt = np.empty(cap)
    st_tool = np.empty((cap, 2))
    st_dt[0] = dt
    st_tool[0, 0] = tool[0]
    st_tool[0, 1] = tool[1]
    top = 1
    cur_tool = tool_prev.copy()
    iters = 0
    res = 0.0
    while top > 0:
        top -= 1
        h = st_dt[top]
        goal = st_tool[top].copy()
        xn, vn, e1n, pn, tn, cn, iters, status, res = one_step(
            x, v, e1, p, ten, con, cur_tool, goal, h, dynamic, fpar, links, masses,
            ob_i, ob_f, ob_v, max_newton, stats)
        if status == OK:
            x, v, e1, p, ten, con = xn, vn, e1n, pn, tn, cn
            cur_tool = goal
            stats[ST_SUBSTEPS] += 1
            continue
        if 0.5 * h < min_dt or top + 2 > cap:
            return x, v, e1, p, ten, con, cur_tool, iters, status, res
        if np.isfinite(cur_tool[0]) and np.isfinite(cur_tool[1]):
            mx = 0.5 * (cur_tool[0] + goal[0])
            mz = 0.5 * (cur_tool[1] + goal[1])
        else:
            mx = goal[0]
            mz = goal[1]
        st_dt[top] = 0.5 * h                # second half, done after the first
        st_tool[top, 0] = goal[0]
        st_tool[top, 1] = goal[1]
        st_dt[top + 1] = 0.5 * h            # first half
        st_tool[top + 1, 0] = mx
        st_tool[top + 1, 1] = mz
        top += 2
    return x, v, e1, p, ten, con, cur_tool, iters, OK, res


@njit(**JIT)
def advance_fixed(x, v, e1, p, ten, con, tool, dt, n_steps, dynamic, fpar, links, masses,
                  ob_i, ob_f, ob_v, max_newton, stats):
    """``n_steps`` steps of ``dt`` [s] with the tool standing at ``tool`` (the settle)."""
    iters = 0
    res = 0.0
    status = OK
    cur = tool.copy()
    for _ in range(n_steps):
        x, v, e1, p, ten, con, cur, iters, status, res = advance(
            x, v, e1, p, ten, con, cur, tool, dt, dynamic, dt / 256.0, fpar, links, masses,
            ob_i, ob_f, ob_v, max_newton, stats)
        if status != OK:
            break
    return x, v, e1, p, ten, con, cur, iters, status, res


@njit(**JIT)
def advance_path(x, v, e1, p, ten, con, tool_prev, dts, tools, dynamic, fpar, links, masses,
                 ob_i, ob_f, ob_v, max_newton, stats, rx, rv, re1, rp, rten, rcon, rit):
    """Steps of ``dts`` (K,) [s], the tool ending step k at ``tools[k]`` [m], each with the
    half-step retries of :func:`advance`; step k's state is written to ``rx[k]`` ... (the
    record arrays).  Returns (steps done, status, residual [N]): fewer than K on failure."""
    cur = tool_prev.copy()
    for k in range(dts.shape[0]):
        dt = dts[k]
        x, v, e1, p, ten, con, cur, iters, status, res = advance(
            x, v, e1, p, ten, con, cur, tools[k], dt, dynamic, dt / 256.0, fpar, links,
            masses, ob_i, ob_f, ob_v, max_newton, stats)
        if status != OK:
            return k, status, res
        rx[k] = x
        rv[k] = v
        re1[k] = e1
        rp[k] = p
        rten[k] = ten
        rcon[k] = con
        rit[k] = iters
    return dts.shape[0], OK, 0.0
