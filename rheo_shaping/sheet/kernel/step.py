"""The sheet step as one compiled (numba) kernel: the only implementation of the step.

:class:`rheo_shaping.sheet.sheet.SheetModel` packs its chain, obstacles and effects
into a few arrays (:func:`pack_model`) and calls :func:`advance`, which takes
one step of ``dt`` [s] (with the half-step retries) or :func:`advance_fixed`,
which takes many equal steps (the inertial settle) without returning to
Python in between.  Everything the step needs is here, compiled: the
three-element link update (material.py's exact step, paper Eq. 2-5), the
obstacles' signed distances, normals and level-set curvature (shapes as small
array descriptions, :func:`shape_eval`), the incremental potential with its
gradient and banded Hessian, the contact-set prediction, a banded Cholesky
solve (half bandwidth 3, 4 with bending), the backtracking line search, and
every effect of :mod:`rheo_shaping.sheet.effects` (friction, bending, Kelvin c1,
power law, thinning, tool offset, mass error).

Compiled code is cached on disk (``cache=True``) in a user cache directory,
so a read-only install (colcon prefix, site-packages) compiles once per user:
``$NUMBA_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/rheo_shaping/numba``
(``~/.cache/rheo_shaping/numba``).  The cache of this file is found by the
file's content, not its path (:class:`_ContentCacheLocator`), so every install
of the same source (a checkout, site-packages, a colcon prefix) shares it.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path


def user_cache_dir() -> str:
    """Directory [path] where the compiled kernel is cached for this user."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return str(Path(base) / "rheo_shaping" / "numba")


if not os.environ.get("NUMBA_CACHE_DIR"):
    os.environ["NUMBA_CACHE_DIR"] = user_cache_dir()
    if "numba" in sys.modules:                     # numba read its config already
        sys.modules["numba"].config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]

import hashlib  # noqa: E402
import math  # noqa: E402

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402
from numba.core import caching as _caching  # noqa: E402


class _ContentCacheLocator(_caching.UserProvidedCacheLocator):
    """numba's user-directory cache, with the folder named by the source file's content
    (SHA-256) instead of its directory: a new install of the same source finds the code
    compiled by an earlier one (numba checks its own version and the CPU in the index)."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        with open(py_file, "rb") as fh:
            digest = hashlib.sha256(fh.read()).hexdigest()[:20]
        self._cache_path = os.path.join(_caching.config.CACHE_DIR, f"rheo_shaping_{digest}")

    @classmethod
    def from_function(cls, py_func, py_file):
        if Path(py_file).resolve() != Path(__file__).resolve():
            return None                           # only this module's functions
        return super().from_function(py_func, py_file)


if _ContentCacheLocator not in _caching.CacheImpl._locator_classes:
    _caching.CacheImpl._locator_classes.insert(0, _ContentCacheLocator)

#: Obstacle kinds of the array description (``Shape.kernel_description``).
CAKE_KIND, PLANE_KIND, POLYGON_KIND = 0, 1, 2

#: Status codes of a step.
OK, NOT_CONVERGED, NOT_SPD = 0, 1, 2

#: Counters returned in ``stats``: Newton iterations, energy evaluations, banded solves,
#: sub-steps taken (> 1: half-step retries), failed minimisations.
ST_NEWTON, ST_EVAL, ST_SOLVE, ST_SUBSTEPS, ST_FAILED = 0, 1, 2, 3, 4

# indices into the packed float parameters
(P_RADIUS, P_GRAVITY, P_KC, P_TOL, P_THIN, P_PLN, P_PLREF, P_EPS, P_SHX, P_SHZ,
 P_TOPX, P_TOPZ, P_BOTX, P_BOTZ, P_BENDING, P_SIZE) = range(16)

_TINY = 1e-300
_JIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")


# ------------------------------------------------------------------------ geometry
@njit(**_JIT)
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
    dd = dist if dist > _TINY else _TINY
    kap = 1.0 / dd if (bt <= 0.0 or bt >= 1.0) else 0.0
    if nv == 2:                                     # capsule: no interior
        if dist > 0.0:
            return dist - rad, bdx / dd, bdz / dd, kap
        return dist - rad, verts[0, 5], verts[0, 6], 0.0
    if smax > 0.0:
        return dist - rad, bdx / dd, bdz / dd, kap
    return smax - rad, snx, snz, 0.0


@njit(**_JIT)
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


# --------------------------------------------------------------------- link law
@njit(**_JIT)
def _factors(k1, c1, c2, dt):
    """(r, eps, g) of material.step_factors for one unit."""
    r = 1.0 / (1.0 + c1 / c2)
    x = k1 * dt / (c1 + c2)
    if not np.isfinite(x):
        x = 0.0
    eps = math.exp(-x)
    g = 1.0 - 0.5 * x if x < 1e-8 else -math.expm1(-x) / x
    return r, eps, g


@njit(**_JIT)
def link_constants(links, e1, p, tension, fpar):
    """k1, c1, c2 (N+1,) of the links over a step: thinning (L/(L+p))^b and the power-law
    c2 (F/F_ref)^(1-1/n), both lagged on the state (rheo_shaping.sheet.effects)."""
    m = links.shape[1]
    k1 = links[1].copy()
    c1 = links[2].copy()
    c2 = links[3].copy()
    b = fpar[P_THIN]
    if b > 0.0:
        for i in range(m):
            L = links[0, i]
            pp = p[i] if p[i] > 0.0 else 0.0
            s = (L / (L + pp)) ** b
            k1[i] *= s
            c1[i] *= s
            c2[i] *= s
    nexp = fpar[P_PLN]
    if nexp != 1.0:
        ref = fpar[P_PLREF]
        for i in range(m):
            F = tension[i] if tension[i] > 1e-3 * ref else 1e-3 * ref
            c2[i] *= (F / ref) ** (1.0 - 1.0 / nexp)
    return k1, c1, c2


# --------------------------------------------------------------------- band solve
@njit(**_JIT)
def band_cholesky(band, kd, L):
    """Cholesky H = L L^T of a banded SPD matrix: ``band[i, k] = H[i, i+k]`` (k <= kd <= 4),
    ``L[i, k] = L[i, i-k]`` and ``L[i, 5] = 1 / L[i, i]``.  False when H is not positive
    definite."""
    m = band.shape[0]
    for j in range(m):
        s = band[j, 0]
        k0 = j - kd if j - kd > 0 else 0
        for k in range(k0, j):
            lv = L[j, j - k]
            s -= lv * lv
        if not s > 0.0:
            return False
        ljj = math.sqrt(s)
        inv = 1.0 / ljj
        L[j, 0] = ljj
        L[j, 5] = inv
        iend = j + kd + 1 if j + kd + 1 < m else m
        for i in range(j + 1, iend):
            s = band[j, i - j]
            k0 = i - kd if i - kd > 0 else 0
            for k in range(k0, j):
                s -= L[i, i - k] * L[j, j - k]
            L[i, i - j] = s * inv
    return True


@njit(**_JIT)
def band_solve(L, kd, b, out):
    """``out`` = -H^-1 b from the factor of :func:`band_cholesky` (the Newton step)."""
    m = L.shape[0]
    for i in range(m):
        s = -b[i]
        k0 = i - kd if i - kd > 0 else 0
        for k in range(k0, i):
            s -= L[i, i - k] * out[k]
        out[i] = s * L[i, 5]
    for i in range(m - 1, -1, -1):
        s = out[i]
        kend = i + kd + 1 if i + kd + 1 < m else m
        for k in range(i + 1, kend):
            s -= L[k, k - i] * out[k]
        out[i] = s * L[i, 5]


# ------------------------------------------------------------------- the potential
@njit(**_JIT)
def _obstacle_offset(ob_i, j, tool):
    """Offset (ox, oz) of obstacle j and whether it is present (a moving one needs a pose)."""
    if ob_i[j, 2] == 1:
        if not (np.isfinite(tool[0]) and np.isfinite(tool[1])):
            return 0.0, 0.0, False
        return tool[0], tool[1], True
    return 0.0, 0.0, True


@njit(**_JIT)
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


@njit(**_JIT)
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
        l = math.sqrt(dx * dx + dz * dz)
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
        ox, oz, here = _obstacle_offset(ob_i, o, tool)
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


@njit(**_JIT)
def _remove_curvature(band, curv):
    for j in range(curv.shape[0]):
        band[2 * j, 0] -= curv[j, 0]
        band[2 * j + 1, 0] -= curv[j, 1]
        band[2 * j, 1] -= curv[j, 2]


@njit(**_JIT)
def _maxabs(a):
    m = 0.0
    for v in a.reshape(a.size):
        if abs(v) > m:
            m = abs(v)
    return m


@njit(**_JIT)
def _pattern_hash(forced):
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


@njit(**_JIT)
def newton_step(grad, band, has_curv, curv, gd, gn, present, radius, kc, kd, step, work,
                bb, fset, stats):
    """Newton step (into ``step`` (N, 2)) with the contact set predicted on the quadratic
    model: masses the plain step would push into an obstacle get its penalty,
    linearised; masses the model would then hold adhesively are let go (a few banded
    solves at most, only when the set changes).  The set starts from ``fset`` (the last
    prediction, or the state's contacts) and is written back to it.  Where the exact Hessian is not SPD its
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
        _remove_curvature(band, curv)
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
        h = _pattern_hash(forced)
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


@njit(**_JIT)
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
        if _maxabs(grad) < tol:
            return x, it - 1, OK, _maxabs(grad), gd, gn, present
        stats[ST_NEWTON] += 1
        sband = band.copy()
        if not newton_step(grad, sband, has_curv, curv, gd, gn, present, radius, kc, kd,
                           step, work, wband, fset, stats):
            return x, it, NOT_SPD, _maxabs(grad), gd, gn, present
        slope = 0.0
        for j in range(n):
            slope += grad[j, 0] * step[j, 0] + grad[j, 1] * step[j, 1]
        if slope >= 0.0:   # the contact prediction spoilt descent: Gauss-Newton step
            sband[:, :] = band
            if has_curv:
                _remove_curvature(sband, curv)
            if not band_cholesky(sband, kd, work[0]):
                return x, it, NOT_SPD, _maxabs(grad), gd, gn, present
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
        if alpha * _maxabs(step) < 1e-14:
            return x, it, OK, _maxabs(grad), gd, gn, present
    res = _maxabs(grad)
    if res < 1e3 * tol:
        return x, max_newton, OK, res, gd, gn, present
    return x, max_newton, NOT_CONVERGED, res, gd, gn, present


# ------------------------------------------------------------------------ the step
@njit(**_JIT)
def _friction_setup(x, contact, tool_prev, tool_real, ob_i, ob_f, ob_v):
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


@njit(**_JIT)
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
        r, eps, g = _factors(k1[i], c1[i], c2[i], dt)
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
    fr_on, fr_tang, fr_mun, fr_move = _friction_setup(x0, con0, real_prev, real, ob_i, ob_f,
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
        l = math.sqrt((bx - ax) ** 2 + (bz - az) ** 2)
        delta = l - free[i]
        r, eps, g = _factors(k1[i], c1[i], c2[i], dt)
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


@njit(**_JIT)
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


@njit(**_JIT)
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


@njit(**_JIT)
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


def pack_model(constants, obstacles, reach, mu, kc: float, force_tol: float, effects):
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
