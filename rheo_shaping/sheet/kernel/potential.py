"""The incremental potential of a step: energy, gradient and banded Hessian (compiled)."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .consts import (JIT, PLANE_KIND, P_BENDING, P_BOTX, P_BOTZ, P_EPS, P_KC, P_RADIUS, P_TOPX,
                     P_TOPZ)
from .shapes import shape_eval


# ------------------------------------------------------------------- the potential
@njit(**JIT)
def obstacle_offset(ob_i, j, tool):
    """Offset (ox, oz) of obstacle j and whether it is present (a moving one needs a pose)."""
    if ob_i[j, 2] == 1:
        if not (np.isfinite(tool[0]) and np.isfinite(tool[1])):
            return 0.0, 0.0, False
        return tool[0], tool[1], True
    return 0.0, 0.0, True


@njit(**JIT)
def bending_terms(x, kb, top, bot, grad):
    """Energy [J] of 1/2 EI/h^3 |x_i-1 - 2 x_i + x_i+1|^2 (kb = EI/h^3 per mass [N/m]),
    its gradient added to ``grad`` (N, 2)."""
    n = x.shape[0]
    energy = 0.0
    for i in range(n):
        for c in range(2):
            a = top[c] if i == 0 else x[i - 1, c]
            b = bot[c] if i == n - 1 else x[i + 1, c]
            D = a - 2.0 * x[i, c] + b
            kD = kb[i] * D
            energy += 0.5 * kD * D
            if i > 0:
                grad[i - 1, c] += kD
            grad[i, c] -= 2.0 * kD
            if i < n - 1:
                grad[i + 1, c] += kD
    return energy


@njit(**JIT)
def evaluate(x, x_pred, inertia, S, L_star, weight, kb, fpar, ob_i, ob_f, ob_v, tool,
             fr_on, fr_tang, fr_mun, fr_x0, fr_move, kd,
             grad, band, gd, gn, present, curv):
    """Energy [J] of the step's potential at x (N, 2); fills its gradient ``grad`` [N],
    the banded Hessian ``band`` and the geometry of the present obstacles (``gd``
    distances, ``gn`` normals, ``present``); ``curv`` (N, 3) the contacts' curvature part
    of the diagonal blocks.  Returns (energy, has_curv)."""
    n = x.shape[0]
    radius = fpar[P_RADIUS]
    kc = fpar[P_KC]
    band[:, :] = 0.0
    energy = 0.0
    hxx_prev = 0.0
    hzz_prev = 0.0
    hxz_prev = 0.0
    fx_prev = 0.0
    fz_prev = 0.0
    for i in range(n + 1):
        ax = fpar[P_TOPX] if i == 0 else x[i - 1, 0]
        az = fpar[P_TOPZ] if i == 0 else x[i - 1, 1]
        bx = fpar[P_BOTX] if i == n else x[i, 0]
        bz = fpar[P_BOTZ] if i == n else x[i, 1]
        dx = bx - ax
        dz = bz - az
        l = math.sqrt(dx * dx + dz * dz)  # noqa: E741
        ux = dx / l
        uz = dz / l
        st = l - L_star[i]
        if st < 0.0:
            st = 0.0
        T = S[i] * st
        energy += 0.5 * T * st
        fx = T * ux
        fz = T * uz
        a = S[i] if st > 0.0 else 0.0
        b = T / l
        uxx = ux * ux
        uzz = uz * uz
        uxz = ux * uz
        hxx = a * uxx + b * (1.0 - uxx)
        hzz = a * uzz + b * (1.0 - uzz)
        hxz = (a - b) * uxz
        if i > 0:
            j = i - 1                       # mass j: link j (before) and link i (after)
            ddx = x[j, 0] - x_pred[j, 0]
            ddz = x[j, 1] - x_pred[j, 1]
            energy += 0.5 * inertia[j] * (ddx * ddx + ddz * ddz) + weight[j] * x[j, 1]
            grad[j, 0] = inertia[j] * ddx + fx_prev - fx
            grad[j, 1] = inertia[j] * ddz + weight[j] + fz_prev - fz
            band[2 * j, 0] = inertia[j] + hxx_prev + hxx
            band[2 * j + 1, 0] = inertia[j] + hzz_prev + hzz
            band[2 * j, 1] = hxz_prev + hxz
            if i < n:                       # coupling of masses j and j+1 through link i
                band[2 * j + 1, 1] = -hxz
                band[2 * j, 2] = -hxx
                band[2 * j + 1, 2] = -hzz
                band[2 * j, 3] = -hxz
        hxx_prev = hxx
        hzz_prev = hzz
        hxz_prev = hxz
        fx_prev = fx
        fz_prev = fz
    # friction: smoothed Coulomb dissipation potential (lagged normal force and tangent)
    eps = fpar[P_EPS]
    eps2 = eps * eps
    for o in range(fr_on.shape[0]):
        if not fr_on[o]:
            continue
        for j in range(n):
            mun = fr_mun[o, j]
            if mun == 0.0:
                continue
            tx = fr_tang[o, j, 0]
            tz = fr_tang[o, j, 1]
            u = (x[j, 0] - fr_x0[j, 0] - fr_move[o, 0]) * tx \
                + (x[j, 1] - fr_x0[j, 1] - fr_move[o, 1]) * tz
            root = math.sqrt(u * u + eps2)
            energy += mun * (root - eps)
            fs = mun * u / root
            grad[j, 0] += fs * tx
            grad[j, 1] += fs * tz
            hf = mun * eps2 / (root * root * root)
            band[2 * j, 0] += hf * tx * tx
            band[2 * j + 1, 0] += hf * tz * tz
            band[2 * j, 1] += hf * tx * tz
    # contacts: 1/2 K_c (r - d)^2 and its exact Hessian, curvature part included
    curv[:, :] = 0.0
    has_curv = False
    for o in range(ob_i.shape[0]):
        kind = ob_i[o, 0]
        nv = ob_i[o, 1]
        ox, oz, here = obstacle_offset(ob_i, o, tool)
        if here and ob_i[o, 2] == 1:
            # no sphere within reach: no contact, nothing to predict
            reach = ob_f[o, 1] + radius + 2e-3
            near = False
            for j in range(n):
                rx = x[j, 0] - ox
                rz = x[j, 1] - oz
                if rx * rx + rz * rz <= reach * reach:
                    near = True
                    break
            here = near
        present[o] = here
        if not here:
            continue
        for j in range(n):
            d, nx, nz, kap = shape_eval(kind, nv, ob_v[o], ob_f[o, 0], x[j, 0], x[j, 1], ox, oz)
            gd[o, j] = d
            gn[o, j, 0] = nx
            gn[o, j, 1] = nz
            pen = radius - d
            if pen > 0.0:
                fp = kc * pen
                energy += 0.5 * fp * pen
                grad[j, 0] -= fp * nx
                grad[j, 1] -= fp * nz
                band[2 * j, 0] += kc * nx * nx
                band[2 * j + 1, 0] += kc * nz * nz
                band[2 * j, 1] += kc * nx * nz
                if kind != PLANE_KIND:
                    has_curv = True
                    # -K_c pen kappa (I - n n^T): round a corner of radius R, kappa = 1/(d + R)
                    bb = -kc * pen * kap
                    cxx = bb * (1.0 - nx * nx)
                    czz = bb * (1.0 - nz * nz)
                    cxz = -bb * nx * nz
                    band[2 * j, 0] += cxx
                    band[2 * j + 1, 0] += czz
                    band[2 * j, 1] += cxz
                    curv[j, 0] += cxx
                    curv[j, 1] += czz
                    curv[j, 2] += cxz
    if fpar[P_BENDING] > 0.0:
        top = np.array((fpar[P_TOPX], fpar[P_TOPZ]))
        bot = np.array((fpar[P_BOTX], fpar[P_BOTZ]))
        energy += bending_terms(x, kb, top, bot, grad)
        for j in range(n):
            dg = 4.0 * kb[j]
            if j > 0:
                dg += kb[j - 1]
            if j < n - 1:
                dg += kb[j + 1]
            band[2 * j, 0] += dg
            band[2 * j + 1, 0] += dg
            if j < n - 1:
                o1 = -2.0 * (kb[j] + kb[j + 1])
                band[2 * j, 2] += o1
                band[2 * j + 1, 2] += o1
            if j < n - 2:
                band[2 * j, 4] += kb[j + 1]
                band[2 * j + 1, 4] += kb[j + 1]
    return energy, has_curv
