"""One step's linear system: links, contact with friction, bending, air damping."""
from __future__ import annotations

import math

from numba import njit

from .consts import (I_AIR, I_CN, I_EI, I_KC, I_KT, I_MU_MOULD, I_MU_TOOL, JIT, TOOL)
from .links import add_block
from .obstacles import contact_scale


@njit(**JIT)
def add_contact(ab, rhs, i, o, xk, dlt, x, g0, n0, ovel, opos, anc, has, par, h, fad):
    """Add the contact of mass ``i`` on obstacle ``o`` at the iterate ``xk`` = ``x`` +
    ``dlt`` to the step's Newton system: the penalty kc (-gap) along the normal
    (linearised, so a contact that starts this step acts), the normal damping cn on the
    velocity dlt/h relative to the obstacle, and Coulomb friction: a stick spring kt to an
    anchor fixed on the obstacle while kt |s| <= mu F_n + fad, else the slip force
    mu F_n + fad (``fad`` [N]: a sticky mould's shear strength at this mass, 0 on the
    tool)."""
    soft = contact_scale(par, o)
    kc = par[I_KC] / soft
    cn = par[I_CN] / math.sqrt(soft)
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
    kt = par[I_KT] / soft
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
    adhesion ``fadh``; ``grav`` (N,) [m/s^2] per mass), ``ab`` = dR/d(dlt) in band form.  On
    the ``first`` iterate a link is taut if it is now or would be at the predicted length,
    later if it is now."""
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
        rhs[2 * i + 1] -= mi * grav[i]
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
