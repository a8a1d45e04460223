"""Newton's method with the contact-set prediction and a backtracking line search."""
from __future__ import annotations

import numpy as np
from numba import njit

from .consts import (JIT, NOT_CONVERGED, NOT_SPD, OK, P_KC, P_RADIUS, P_TOL, ST_EVAL, ST_NEWTON,
                     ST_SOLVE)
from .links import band_cholesky, band_solve
from .potential import evaluate


@njit(**JIT)
def remove_curvature(band, curv):
    for j in range(curv.shape[0]):
        band[2 * j, 0] -= curv[j, 0]
        band[2 * j + 1, 0] -= curv[j, 1]
        band[2 * j, 1] -= curv[j, 2]


@njit(**JIT)
def maxabs(a):
    m = 0.0
    for v in a.reshape(a.size):
        if abs(v) > m:
            m = abs(v)
    return m


@njit(**JIT)
def pattern_hash(forced):
    """64-bit hash of a predicted contact set (order-independent sum of mixed indices)."""
    h = 0
    k = 0
    for o in range(forced.shape[0]):
        for j in range(forced.shape[1]):
            if forced[o, j]:
                z = (k + 1) * 6364136223846793005
                z ^= z >> 29
                z *= 1442695040888963407
                h += z
            k += 1
    return h


@njit(**JIT)
def newton_step(grad, band, has_curv, curv, gd, gn, present, radius, kc, kd, step, work,
                bb, fset, stats):
    """Newton step (into ``step`` (N, 2)) with the contact set predicted on the quadratic
    model: masses the plain step would push into an obstacle get its penalty,
    linearised; masses the model would then hold adhesively are let go (a few banded
    solves at most, only when the set changes).  The set starts from ``fset`` (the last
    prediction, or the state's contacts) and is written back to it.  Where the exact Hessian is not
    SPD its
    curvature part is dropped (Gauss-Newton; ``band`` is modified).  False: no SPD
    system."""
    n = grad.shape[0]
    n_ob = present.shape[0]
    m = 2 * n
    L0 = work[0]
    Lf = work[1]
    if not band_cholesky(band, kd, L0):
        if not has_curv:
            return False
        remove_curvature(band, curv)
        if not band_cholesky(band, kd, L0):
            return False
    g = grad.reshape(m)
    s = step.reshape(m)
    # warm start: the set of the last prediction and the state's contacts (``fset``), for
    # the spheres that are out of contact now; without it contact re-enters ~8 spheres a
    # round and a step costs O(N^2)
    forced = np.zeros((n_ob, n), dtype=np.bool_)
    any_forced = False
    for o in range(n_ob):
        if present[o]:
            for j in range(n):
                if fset[o, j] and gd[o, j] >= radius:
                    forced[o, j] = True
                    any_forced = True
    # rounds until the predicted set settles (one or two with the warm start); a repeated
    # set is a cycle, after which spheres may only enter, so the set grows and the loop ends
    cap = 4 * n_ob * n + 16
    seen = np.empty(cap, dtype=np.int64)
    n_seen = 0
    only_enter = False
    g2 = np.empty(m)
    while True:
        if any_forced:
            g2[:] = g
            bb[:, :] = band
            for o in range(n_ob):
                if not present[o]:
                    continue
                for j in range(n):
                    if forced[o, j]:
                        nx = gn[o, j, 0]
                        nz = gn[o, j, 1]
                        f = kc * (radius - gd[o, j])
                        g2[2 * j] -= f * nx
                        g2[2 * j + 1] -= f * nz
                        bb[2 * j, 0] += kc * nx * nx
                        bb[2 * j + 1, 0] += kc * nz * nz
                        bb[2 * j, 1] += kc * nx * nz
            if not band_cholesky(bb, kd, Lf):
                return False
            band_solve(Lf, kd, g2, s)
        else:
            band_solve(L0, kd, g, s)
        stats[ST_SOLVE] += 1
        changed = False
        any_forced = False
        for o in range(n_ob):
            if not present[o]:
                continue
            for j in range(n):
                pen_new = radius - gd[o, j] - (gn[o, j, 0] * step[j, 0] + gn[o, j, 1] * step[j, 1])
                f = forced[o, j]
                if (not f) and gd[o, j] >= radius and pen_new > 1e-12:
                    forced[o, j] = True
                    changed = True
                elif f and pen_new < 0.0 and not only_enter:
                    forced[o, j] = False
                    changed = True
                any_forced = any_forced or forced[o, j]
        if not changed:
            break
        h = pattern_hash(forced)
        for k in range(n_seen):
            if seen[k] == h:
                only_enter = True
                break
        if n_seen == cap:
            only_enter = True
        else:
            seen[n_seen] = h
            n_seen += 1
    fset[:, :] = forced
    return True


@njit(**JIT)
def minimise(x, x_pred, inertia, S, L_star, weight, kb, fpar, ob_i, ob_f, ob_v, tool,
             fr_on, fr_tang, fr_mun, fr_x0, fr_move, kd, max_newton, fset, stats):
    """Newton's method with backtracking on the step's potential from ``x`` (N, 2).

    Returns (x, iterations, status, force residual [N], gd, gn, present) with the
    geometry of the final iterate."""
    n = x.shape[0]
    n_ob = ob_i.shape[0]
    m = 2 * n
    tol = fpar[P_TOL]
    radius = fpar[P_RADIUS]
    kc = fpar[P_KC]
    grad = np.empty((n, 2))
    band = np.empty((m, 5))
    gd = np.zeros((n_ob, n))
    gn = np.zeros((n_ob, n, 2))
    present = np.zeros(n_ob, dtype=np.bool_)
    curv = np.empty((n, 3))
    t_grad = np.empty((n, 2))
    t_band = np.empty((m, 5))
    t_gd = np.zeros((n_ob, n))
    t_gn = np.zeros((n_ob, n, 2))
    t_present = np.zeros(n_ob, dtype=np.bool_)
    t_curv = np.empty((n, 3))
    work = np.zeros((2, m, 6))
    wband = np.empty((m, 5))
    step = np.empty((n, 2))
    trial = np.empty((n, 2))
    x = x.copy()
    energy, has_curv = evaluate(x, x_pred, inertia, S, L_star, weight, kb, fpar, ob_i, ob_f,
                                ob_v, tool, fr_on, fr_tang, fr_mun, fr_x0, fr_move, kd,
                                grad, band, gd, gn, present, curv)
    stats[ST_EVAL] += 1
    for it in range(1, max_newton + 1):
        if maxabs(grad) < tol:
            return x, it - 1, OK, maxabs(grad), gd, gn, present
        stats[ST_NEWTON] += 1
        sband = band.copy()
        if not newton_step(grad, sband, has_curv, curv, gd, gn, present, radius, kc, kd,
                           step, work, wband, fset, stats):
            return x, it, NOT_SPD, maxabs(grad), gd, gn, present
        slope = 0.0
        for j in range(n):
            slope += grad[j, 0] * step[j, 0] + grad[j, 1] * step[j, 1]
        if slope >= 0.0:   # the contact prediction spoilt descent: Gauss-Newton step
            sband[:, :] = band
            if has_curv:
                remove_curvature(sband, curv)
            if not band_cholesky(sband, kd, work[0]):
                return x, it, NOT_SPD, maxabs(grad), gd, gn, present
            band_solve(work[0], kd, grad.reshape(m), step.reshape(m))
            stats[ST_SOLVE] += 1
            slope = 0.0
            for j in range(n):
                slope += grad[j, 0] * step[j, 0] + grad[j, 1] * step[j, 1]
        alpha = 1.0
        while True:
            for j in range(n):
                trial[j, 0] = x[j, 0] + alpha * step[j, 0]
                trial[j, 1] = x[j, 1] + alpha * step[j, 1]
            e_trial, t_has = evaluate(trial, x_pred, inertia, S, L_star, weight, kb, fpar,
                                      ob_i, ob_f, ob_v, tool, fr_on, fr_tang, fr_mun, fr_x0,
                                      fr_move, kd, t_grad, t_band, t_gd, t_gn, t_present,
                                      t_curv)
            stats[ST_EVAL] += 1
            # the roundoff allowance lets converged Newton steps through
            if e_trial <= energy + 1e-4 * alpha * slope + 1e-15 * abs(energy) or alpha < 1e-8:
                break
            alpha *= 0.5
        x, trial = trial, x
        grad, t_grad = t_grad, grad
        band, t_band = t_band, band
        gd, t_gd = t_gd, gd
        gn, t_gn = t_gn, gn
        present, t_present = t_present, present
        curv, t_curv = t_curv, curv
        energy = e_trial
        has_curv = t_has
        if alpha * maxabs(step) < 1e-14:
            return x, it, OK, maxabs(grad), gd, gn, present
    res = maxabs(grad)
    if res < 1e3 * tol:
        return x, max_newton, OK, res, gd, gn, present
    return x, max_newton, NOT_CONVERGED, res, gd, gn, present
