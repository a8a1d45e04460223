"""The sheet: a chain of lumped masses joined by three-element links (Sec. 4.1).

N masses (spheres of radius ``r`` = half the sheet thickness) hang between
two fixed bonds and are joined by N + 1 links.  Link i joins node i-1 and
node i, where node -1 is the cake-top bond and node N the workplane bond.
Every link is a three-element unit with constants scaled to its rest length
(:mod:`rheo_shaping.material`); it carries tension only (a slack link buckles
and carries nothing).  Spheres touch the obstacles (cake, workplane, tool)
without friction and without interpenetration.

One time step is implicit (backward Euler in the positions, the exact
three-element update in the links).  Over a step the link force is affine in
the link length (:func:`rheo_shaping.material.step_coefficients`), so the new
positions minimise the incremental potential

    E(x) = sum m |x - x_pred|^2 / (2 dt^2) + sum 1/2 S (l - L*)_+^2
           + sum m g z + sum 1/2 K_c (r - d_obstacle(x))_+^2,

a convex function but for the contact terms.  ``x_pred = x + dt v`` with
inertia (``dynamic=True``), ``x_pred = x`` in the quasi-static regime where the
first term is only a tiny proximal regulariser (m/dt^2 ~ 1e-2 N/m against link
stiffnesses ~ 1e3 N/m).  Newton's method with a banded Cholesky solve and a
backtracking line search finds the minimiser; its Hessian is block
tridiagonal (half bandwidth 3).  The penalty stiffness K_c makes the largest
penetration F_contact / K_c (0.1 um per newton at the default 1e7 N/m).
See docs/model.md for why this formulation was chosen.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol, Sequence

import numpy as np
from scipy.linalg.lapack import dpbsv

from .material import elongation_step, step_coefficients


class Shape(Protocol):
    """What the sheet needs of an obstacle (see :mod:`rheo_shaping.geometry`)."""

    def signed_distance(self, points: np.ndarray, offset=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        ...


@dataclass(frozen=True)
class Obstacle:
    """A rigid obstacle; ``moving`` ones are placed at the tool pose each step."""

    name: str
    shape: Shape
    moving: bool = False


@dataclass(frozen=True)
class ChainConstants:
    """Everything constant about one chain (SI units, arrays over links/masses)."""

    anchor_top: np.ndarray      # (2,) m, cake-top bond
    anchor_bottom: np.ndarray   # (2,) m, workplane bond
    rest_length: np.ndarray     # (N+1,) m
    k1: np.ndarray              # (N+1,) N/m, scaled to each link's rest length
    c1: np.ndarray              # (N+1,) N s/m
    c2: np.ndarray              # (N+1,) N s/m (inf: no plastic flow)
    mass: np.ndarray            # (N,) kg
    radius: float               # m, sphere radius (half the thickness)
    gravity: float = 9.81       # m/s^2

    def __post_init__(self) -> None:
        n = np.asarray(self.mass).shape[0] if np.ndim(self.mass) == 1 else -1
        if n < 1:
            raise ValueError(f"mass must be a 1-D array of the N >= 1 sphere masses [kg], got shape {np.shape(self.mass)}")
        _check_array("mass", self.mass, n, "kg", positive=True)
        _check_array("rest_length", self.rest_length, n + 1, "m", positive=True)
        _check_array("k1", self.k1, n + 1, "N/m", positive=True)
        _check_array("c1", self.c1, n + 1, "N s/m", positive=False)
        _check_array("c2", self.c2, n + 1, "N s/m", positive=True, allow_inf=True)
        for name in ("anchor_top", "anchor_bottom"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != (2,) or not np.all(np.isfinite(a)):
                raise ValueError(f"{name} must be a finite point (x, z) [m], got {getattr(self, name)!r}")
        if not (np.isfinite(self.radius) and self.radius > 0.0):
            raise ValueError(f"radius = {self.radius!r} m is invalid: expected a finite value > 0")
        if not (np.isfinite(self.gravity) and self.gravity >= 0.0):
            raise ValueError(f"gravity = {self.gravity!r} m/s^2 is invalid: expected a finite value >= 0")

    @property
    def n_masses(self) -> int:
        return int(self.mass.shape[0])


@dataclass(frozen=True)
class SheetEffects:
    """Optional physics the nominal model leaves out (rheo_shaping.effects; all off by default).

    ``friction`` maps obstacle names to Coulomb coefficients; ``bending`` is the
    strip's EI [N m^2]; ``power_law_n`` the flow index of a power-law dashpot
    c2 with reference tension ``power_law_ref`` [N]; ``thinning`` the exponent b
    of the links' cross-section (L / (L + p))^b; ``tool_shift`` [m] where the
    real tool sits relative to the commanded pose.
    """

    friction: tuple[tuple[str, float], ...] = ()
    bending: float = 0.0
    power_law_n: float = 1.0
    power_law_ref: float = 0.5
    thinning: float = 0.0
    tool_shift: tuple[float, float] = (0.0, 0.0)
    friction_slip: float = 1e-7      # m per step: slip within which friction acts as a stiff spring (stick)

    def mu(self, name: str) -> float:
        return dict(self.friction).get(name, 0.0)


@dataclass(frozen=True)
class SheetState:
    """State of the chain at time ``t`` [s]."""

    t: float
    x: np.ndarray          # (N, 2) m, sphere centres
    v: np.ndarray          # (N, 2) m/s
    e1: np.ndarray         # (N+1,) m, elastic (Kelvin-Voigt) elongation
    p: np.ndarray          # (N+1,) m, plastic elongation (dashpot c2)
    tension: np.ndarray    # (N+1,) N
    contact: np.ndarray    # (n_obstacles, N, 2) N, force of each obstacle on each sphere
    tool: np.ndarray       # (2,) m, tool reference point
    newton_iterations: int = 0

    def copy(self) -> "SheetState":
        return replace(self, x=self.x.copy(), v=self.v.copy(), e1=self.e1.copy(),
                       p=self.p.copy(), tension=self.tension.copy(),
                       contact=self.contact.copy(), tool=self.tool.copy())


def _check_array(name: str, values, size: int, unit: str, positive: bool, allow_inf: bool = False) -> None:
    """ValueError naming ``name`` unless ``values`` has ``size`` entries, all valid."""
    a = np.asarray(values, dtype=float)
    if a.shape != (size,):
        raise ValueError(f"{name} must have {size} values [{unit}], got shape {a.shape}")
    bad = np.isnan(a) | (np.isinf(a) if not allow_inf else np.isneginf(a))
    bad |= (a <= 0.0) if positive else (a < 0.0)
    if bad.any():
        i = int(np.argmax(bad))
        want = "> 0" if positive else ">= 0"
        raise ValueError(f"{name}[{i}] = {float(a[i])!r} {unit} is invalid: expected a "
                         f"{'finite ' if not allow_inf else ''}value {want}")


class ConvergenceError(RuntimeError):
    """Newton's method did not converge in a step."""



class SheetModel:
    """Implicit stepping of a chain of masses with tension-only links and contact."""

    def __init__(self, constants: ChainConstants, obstacles: Sequence[Obstacle],
                 contact_stiffness: float = 1e7, force_tol: float = 1e-9,
                 max_newton: int = 50, effects: SheetEffects = SheetEffects()):
        self.c = constants
        self.effects = effects
        self._friction_terms: list = []
        self._shift = np.asarray(effects.tool_shift, dtype=float)
        self._mu = [effects.mu(ob.name) for ob in obstacles]
        self._bending = None
        if effects.bending > 0.0:
            h = 0.5 * (constants.rest_length[:-1] + constants.rest_length[1:])
            self._bending = effects.bending / h ** 3        # N/m per mass, EI / h^3
        self.obstacles = tuple(obstacles)
        self.kc = float(contact_stiffness)
        self.force_tol = float(force_tol)
        self.max_newton = int(max_newton)
        n = constants.n_masses
        self._n = n
        self._weight = np.zeros((n, 2))
        self._weight[:, 1] = constants.mass * constants.gravity
        self._nodes = np.empty((n + 2, 2))
        self._nodes[0] = constants.anchor_top
        self._nodes[-1] = constants.anchor_bottom
        # how far a moving obstacle reaches from its reference point (skip it when farther)
        self._reach = [_reach(ob.shape) if ob.moving else np.inf for ob in self.obstacles]

    # ------------------------------------------------------------------ state
    def initial_state(self, x0: np.ndarray, tool=(np.nan, np.nan), t0: float = 0.0) -> SheetState:
        """Masses at rest at ``x0`` (N, 2), no elastic or plastic elongation yet.

        Links start at their rest lengths' free length: shorter ones are slack,
        longer ones are stretched from the first step on.
        """
        n = self._n
        x0 = np.asarray(x0, dtype=float).reshape(n, 2)
        return SheetState(
            t=t0, x=x0.copy(), v=np.zeros((n, 2)),
            e1=np.zeros(n + 1), p=np.zeros(n + 1),
            tension=np.zeros(n + 1), contact=np.zeros((len(self.obstacles), n, 2)),
            tool=np.asarray(tool, dtype=float).copy())

    def nodes(self, x: np.ndarray) -> np.ndarray:
        """Bond, mass and bond positions (N+2, 2) [m] (a new array)."""
        return np.vstack((self.c.anchor_top, x, self.c.anchor_bottom))

    def link_lengths(self, x: np.ndarray) -> np.ndarray:
        d = np.diff(self.nodes(x), axis=0)
        return np.hypot(d[:, 0], d[:, 1])

    # ------------------------------------------------------------------ step
    def step(self, state: SheetState, dt: float, tool=(np.nan, np.nan),
             dynamic: bool = True, _min_dt: float | None = None) -> SheetState:
        """Advance by ``dt`` [s] with the tool reference point at ``tool`` [m] at the end.

        ``dynamic=True`` (default) is backward Euler: the inertia term is
        m (v_new - v)/dt, physical, and negligible against the links at the
        process's time steps.  ``dynamic=False`` predicts rest (x_pred = x), a
        proximal term that acts like a drag m v/dt.

        A step whose Newton iteration does not converge (a sphere caught on a
        sharp tool corner, a sudden contact) is retried as two half steps, the
        tool moving linearly between its poses, down to 1/256 of ``dt``.
        """
        if _min_dt is None and not (np.isfinite(dt) and dt > 0.0):
            raise ValueError(f"time step dt = {dt!r} s is invalid: expected a finite value > 0")
        min_dt = dt / 256.0 if _min_dt is None else _min_dt
        try:
            return self._step(state, dt, tool, dynamic)
        except ConvergenceError:
            if 0.5 * dt < min_dt:
                raise
        tool = np.asarray(tool, dtype=float)
        mid = 0.5 * (state.tool + tool) if np.all(np.isfinite(state.tool)) else tool
        half = self.step(state, 0.5 * dt, mid, dynamic, min_dt)
        return self.step(half, 0.5 * dt, tool, dynamic, min_dt)

    def _step(self, state: SheetState, dt: float, tool, dynamic: bool) -> SheetState:
        c = self.c
        tool = np.asarray(tool, dtype=float)
        free_length = c.rest_length + state.e1 + state.p
        k1, c1, c2 = self._link_constants(state)
        F0, S = step_coefficients(k1, c1, c2, state.e1, dt)
        L_star = free_length - F0 / S
        inertia = c.mass / dt ** 2
        x_pred = state.x + dt * state.v if dynamic else state.x
        real_tool = tool + self._shift
        offsets = [real_tool if ob.moving else None for ob in self.obstacles]
        self._friction_terms = self._friction_setup(state, real_tool)

        guess = state.x + dt * state.v      # warm start: continue the last motion
        x, iters, geo = self._minimise(guess, x_pred, inertia, S, L_star, offsets)

        l = self.link_lengths(x)
        F, e1, p = elongation_step(k1, c1, c2, state.e1, state.p, l - free_length, dt)
        contact = self._contact_forces(geo)
        for i, _, f_slip in self._friction_eval(x):
            contact[i] -= f_slip
        v = (x - state.x) / dt   # quasi-static: only the warm start of the next step uses it
        return SheetState(t=state.t + dt, x=x, v=v, e1=e1, p=p, tension=F,
                          contact=contact, tool=tool.copy(), newton_iterations=iters)

    # ---------------------------------------------------------------- effects
    def _link_constants(self, state: SheetState):
        """k1, c1, c2 of the links over this step (thinning, power law: lagged on the state)."""
        c, eff = self.c, self.effects
        k1, c1, c2 = c.k1, c.c1, c.c2
        if eff.thinning > 0.0:
            # the section shrinks as the link flows (volume kept): (L / (L + p))^b
            scale = (c.rest_length / (c.rest_length + np.maximum(state.p, 0.0))) ** eff.thinning
            k1, c1, c2 = k1 * scale, c1 * scale, c2 * scale
        if eff.power_law_n != 1.0:
            # dp/dt = (F / c2) (F / F_ref)^(1/n - 1): c2_eff = c2 (F / F_ref)^(1 - 1/n), F lagged
            F = np.maximum(state.tension, 1e-3 * eff.power_law_ref)
            c2 = c2 * (F / eff.power_law_ref) ** (1.0 - 1.0 / eff.power_law_n)
        return k1, c1, c2

    def _friction_setup(self, state: SheetState, real_tool):
        """Per obstacle with friction: (index, tangents t, mu * normal force, start x, obstacle shift)."""
        terms = []
        if not any(self._mu):
            return terms
        prev_tool = state.tool + self._shift
        for i, (ob, mu) in enumerate(zip(self.obstacles, self._mu)):
            if mu <= 0.0:
                continue
            if ob.moving and not (np.all(np.isfinite(prev_tool)) and np.all(np.isfinite(real_tool))):
                continue
            off = prev_tool if ob.moving else (0.0, 0.0)
            _, nrm = ob.shape.signed_distance(state.x, off)
            lam = np.maximum(np.einsum("ij,ij->i", state.contact[i], nrm), 0.0)   # normal force [N]
            if not np.any(lam > 0.0):
                continue
            tang = np.c_[-nrm[:, 1], nrm[:, 0]]
            move = (real_tool - prev_tool) if ob.moving else np.zeros(2)
            terms.append((i, tang, mu * lam, state.x.copy(), move))
        return terms

    def _friction_eval(self, x):
        """(index, energy, friction force on the spheres (N, 2)) of each friction term at ``x``.

        Smoothed Coulomb friction as a dissipation potential (lagged normal force
        and tangent): D = mu N (sqrt(u^2 + eps^2) - eps), u the tangential slip of a
        sphere relative to the obstacle over the step.
        """
        eps = self.effects.friction_slip
        out = []
        for i, tang, mun, x0, move in self._friction_terms:
            u = np.einsum("ij,ij->i", x - x0 - move, tang)
            root = np.sqrt(u * u + eps * eps)
            energy = float(np.dot(mun, root - eps))
            f = (mun * u / root)[:, None] * tang        # gradient of D = force resisting the slip
            out.append((i, energy, f))
        return out

    def _bending_terms(self, x):
        """Energy, gradient (N, 2) and banded Hessian rows of 1/2 EI/h^3 |x_i-1 - 2 x_i + x_i+1|^2."""
        kb = self._bending
        nodes = np.vstack((self.c.anchor_top, x, self.c.anchor_bottom))
        D = nodes[:-2] - 2.0 * nodes[1:-1] + nodes[2:]                   # (N, 2), per mass
        kD = kb[:, None] * D
        energy = 0.5 * float(np.sum(kD * D))
        g_nodes = np.zeros_like(nodes)
        g_nodes[:-2] += kD
        g_nodes[1:-1] -= 2.0 * kD
        g_nodes[2:] += kD
        return energy, g_nodes[1:-1], kb

    # --------------------------------------------------------------- newton
    def _geometry(self, x, offsets):
        """Per present obstacle: (index, signed distance of the centres d [m], normals n)."""
        out = []
        for i, (ob, off) in enumerate(zip(self.obstacles, offsets)):
            if ob.moving:
                if off is None or not np.all(np.isfinite(off)):
                    continue
                # no sphere within reach: no contact, nothing to predict (the exact
                # energy is unchanged; a Newton trial point that comes near is evaluated fully)
                rel = x - off
                if np.min(rel[:, 0] ** 2 + rel[:, 1] ** 2) > (self._reach[i] + self.c.radius + 2e-3) ** 2:
                    continue
            d, nrm = ob.shape.signed_distance(x, off if ob.moving else (0.0, 0.0))
            out.append((i, d, nrm))
        return out

    def _contact_forces(self, geo) -> np.ndarray:
        """Force [N] of each obstacle on each sphere, from the final Newton geometry."""
        forces = np.zeros((len(self.obstacles), self._n, 2))
        for i, d, nrm in geo:
            forces[i] = (self.kc * np.maximum(self.c.radius - d, 0.0))[:, None] * nrm
        return forces

    def _evaluate(self, x, x_pred, inertia, S, L_star, offsets):
        """Energy, gradient (N, 2) and banded Hessian of the step's potential at ``x``."""
        n = self._n
        nodes = self._nodes
        nodes[1:-1] = x
        d = nodes[1:] - nodes[:-1]                      # (N+1, 2)
        l = np.hypot(d[:, 0], d[:, 1])
        u = d / l[:, None]
        stretch = np.maximum(l - L_star, 0.0)
        T = S * stretch                                  # link forces of this iterate
        f = T[:, None] * u                               # (N+1, 2)
        dx = x - x_pred
        energy = 0.5 * (np.dot(inertia, np.einsum("ij,ij->i", dx, dx)) + np.dot(T, stretch)) \
            + np.dot(self._weight[:, 1], x[:, 1])
        grad = inertia[:, None] * dx + self._weight + f[:-1] - f[1:]

        # link Hessian blocks K (u u^T + (l-L)/l (I - u u^T)) for taut links
        a = np.where(stretch > 0.0, S, 0.0)
        b = T / l
        uxx, uzz, uxz = u[:, 0] ** 2, u[:, 1] ** 2, u[:, 0] * u[:, 1]
        hxx = a * uxx + b * (1.0 - uxx)
        hzz = a * uzz + b * (1.0 - uzz)
        hxz = (a - b) * uxz
        dxx = inertia + hxx[:-1] + hxx[1:]
        dzz = inertia + hzz[:-1] + hzz[1:]
        dxz = hxz[:-1] + hxz[1:]
        if self._friction_terms:
            eps2 = self.effects.friction_slip ** 2
            for _, tang, mun, x0, move in self._friction_terms:
                u = np.einsum("ij,ij->i", x - x0 - move, tang)
                root = np.sqrt(u * u + eps2)
                energy += float(np.dot(mun, root - np.sqrt(eps2)))
                grad = grad + (mun * u / root)[:, None] * tang
                hf = mun * eps2 / root ** 3                              # >= 0: convex
                dxx = dxx + hf * tang[:, 0] ** 2
                dzz = dzz + hf * tang[:, 1] ** 2
                dxz = dxz + hf * tang[:, 0] * tang[:, 1]
        geo = self._geometry(x, offsets)
        curv = None          # the contacts' curvature part of the Hessian diagonal blocks
        for i, dist, nrm in geo:
            pen = self.c.radius - dist
            active = pen > 0.0
            if not np.any(active):
                continue
            kp = np.where(active, self.kc, 0.0)
            fp = kp * pen
            energy += 0.5 * np.dot(fp, pen)
            grad -= fp[:, None] * nrm
            dxx = dxx + kp * nrm[:, 0] ** 2
            dzz = dzz + kp * nrm[:, 1] ** 2
            dxz = dxz + kp * nrm[:, 0] * nrm[:, 1]
            # exact Hessian of 1/2 K_c (r - d)^2 adds -K_c pen kappa (I - n n^T): kappa is the
            # curvature of the distance's level set (1/(d + R) round a corner of radius R, 0
            # along a flat face).  Without it Newton crawls round sharp corners.
            kappa = self._curvature(i, x, nrm, active, offsets)
            if kappa is not None:
                b = np.zeros(n)
                b[active] = -self.kc * pen[active] * kappa
                cxx, czz, cxz = b * (1.0 - nrm[:, 0] ** 2), b * (1.0 - nrm[:, 1] ** 2), -b * nrm[:, 0] * nrm[:, 1]
                dxx, dzz, dxz = dxx + cxx, dzz + czz, dxz + cxz
                if curv is None:
                    curv = np.zeros((3, n))
                curv += (cxx, czz, cxz)

        # upper band storage, half bandwidth kd = 3 (4 with bending): ab[kd + i - j, j] = H[i, j]
        kd = 3 if self._bending is None else 4
        ab = np.zeros((kd + 1, 2 * n))
        ab[kd, 0::2] = dxx
        ab[kd, 1::2] = dzz
        ab[kd - 1, 1::2] = dxz
        off_xz = -hxz[1:-1]
        ab[kd - 1, 2::2] = off_xz          # H[z_j, x_j+1]
        ab[kd - 2, 2::2] = -hxx[1:-1]      # H[x_j, x_j+1]
        ab[kd - 2, 3::2] = -hzz[1:-1]      # H[z_j, z_j+1]
        ab[kd - 3, 3::2] = off_xz          # H[x_j, z_j+1]
        if self._bending is not None:
            e_b, g_b, kb = self._bending_terms(x)
            energy += e_b
            grad = grad + g_b
            # mass m is the centre of term m (coefficients 1, -2, 1 on m-1, m, m+1)
            diag = 4.0 * kb
            diag[1:] += kb[:-1]
            diag[:-1] += kb[1:]
            off1 = -2.0 * (kb[:-1] + kb[1:])              # H[m, m+1]
            off2 = kb[1:-1]                               # H[m, m+2]
            ab[kd, 0::2] += diag
            ab[kd, 1::2] += diag
            ab[kd - 2, 2::2] += off1
            ab[kd - 2, 3::2] += off1
            ab[kd - 4, 4::2] += off2
            ab[kd - 4, 5::2] += off2
        if curv is not None:
            geo = _Geo(geo, curv)
        return float(energy), grad, ab, geo

    def _curvature(self, i, x, nrm, active, offsets, h=1e-7):
        """Curvature [1/m] of obstacle i's distance at the active spheres (finite difference
        of the normal along the tangent), or None where it is zero everywhere."""
        ob = self.obstacles[i]
        if isinstance(ob.shape, _FLAT_SHAPES):
            return None
        n_a = nrm[active]
        t = np.c_[-n_a[:, 1], n_a[:, 0]]
        _, n2 = ob.shape.signed_distance(x[active] + h * t, offsets[i] if ob.moving else (0.0, 0.0))
        kappa = np.einsum("ij,ij->i", n2 - n_a, t) / h
        return np.maximum(kappa, 0.0)   # convex obstacles: level sets curve outward

    def _newton_step(self, grad, ab, geo):
        """Newton step with the contact set predicted on the quadratic model.

        Masses the plain step would push into an obstacle get that obstacle's
        penalty, linearised (the gradient of 1/2 K_c (r - d - n.dx)^2 at dx = 0
        and its Hessian K_c n n^T); masses the model would then hold with an
        adhesive (negative) force are let go again.  A few banded solves at
        most, and only when the contact set changes.
        """
        r, kc = self.c.radius, self.kc
        forced = [np.zeros(self._n, dtype=bool) for _ in geo]
        if isinstance(geo, _Geo) and not _positive_definite(ab):
            ab = _without_curvature(ab, geo.curv)   # Gauss-Newton where the exact one is not SPD
        # rounds until the predicted set settles (it may need ~N/8 rounds as contact spreads
        # along the sheet); a repeated set is a cycle, after which spheres may only enter,
        # so the set grows and the loop ends
        seen: set = set()
        only_enter = False
        while True:
            g = grad.copy()
            band = ab
            if any(f.any() for f in forced):
                band = ab.copy()
                for (_, dist, nrm), f in zip(geo, forced):
                    if not f.any():
                        continue
                    kf = np.where(f, kc, 0.0)
                    g -= (kf * (r - dist))[:, None] * nrm
                    kd = band.shape[0] - 1
                    band[kd, 0::2] += kf * nrm[:, 0] ** 2
                    band[kd, 1::2] += kf * nrm[:, 1] ** 2
                    band[kd - 1, 1::2] += kf * nrm[:, 0] * nrm[:, 1]
            step = _solve(band, g)
            changed = False
            for (_, dist, nrm), f in zip(geo, forced):
                pen_new = r - dist - np.einsum("ij,ij->i", nrm, step)
                enter = (~f) & (dist >= r) & (pen_new > 1e-12)
                leave = f & (pen_new < 0.0) & (not only_enter)
                if enter.any() or leave.any():
                    f |= enter
                    f &= ~leave
                    changed = True
            if not changed:
                break
            key = b"".join(f.tobytes() for f in forced)
            if key in seen:
                only_enter = True
            seen.add(key)
        return step, g

    def _minimise(self, x, x_pred, inertia, S, L_star, offsets):
        args = (x_pred, inertia, S, L_star, offsets)
        energy, grad, ab, geo = self._evaluate(x, *args)
        for it in range(1, self.max_newton + 1):
            if np.max(np.abs(grad)) < self.force_tol:
                return x, it - 1, geo
            step, g_model = self._newton_step(grad, ab, geo)
            slope = float(np.dot(grad.reshape(-1), step.reshape(-1)))
            if slope >= 0.0:   # the contact prediction spoilt descent: Gauss-Newton step
                step = _solve(_without_curvature(ab, geo.curv) if isinstance(geo, _Geo) else ab, grad)
                slope = float(np.dot(grad.reshape(-1), step.reshape(-1)))
            alpha = 1.0
            while True:
                trial = x + alpha * step
                e_trial, g_trial, ab_trial, geo_trial = self._evaluate(trial, *args)
                # the roundoff allowance lets converged Newton steps through
                if (e_trial <= energy + 1e-4 * alpha * slope + 1e-15 * abs(energy)
                        or alpha < 1e-8):
                    break
                alpha *= 0.5
            x, energy, grad, ab, geo = trial, e_trial, g_trial, ab_trial, geo_trial
            if np.max(np.abs(alpha * step)) < 1e-14:
                return x, it, geo
        if np.max(np.abs(grad)) < 1e3 * self.force_tol:
            return x, self.max_newton, geo
        raise ConvergenceError(
            f"Newton did not converge in {self.max_newton} iterations "
            f"(force residual {np.max(np.abs(grad)):.3g} N)")


def _reach(shape) -> float:
    """Largest distance [m] of a shape's outline from its reference point."""
    outline = shape.outline(256)
    return float(np.max(np.hypot(outline[:, 0], outline[:, 1])))


def _solve(band: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Newton step (N, 2) from the banded SPD Hessian (LAPACK dpbsv, upper band storage)."""
    _, step, info = dpbsv(band, -grad.reshape(-1))
    if info != 0:  # pragma: no cover - the Hessian is SPD by construction
        raise ConvergenceError(f"Newton system not positive definite (LAPACK dpbsv info {info})")
    return step.reshape(-1, 2)


class _Geo(list):
    """Per-obstacle geometry of an iterate, with the contacts' curvature Hessian part."""

    def __init__(self, items, curv):
        super().__init__(items)
        self.curv = curv


def _without_curvature(ab: np.ndarray, curv: np.ndarray) -> np.ndarray:
    band = ab.copy()
    kd = band.shape[0] - 1
    band[kd, 0::2] -= curv[0]
    band[kd, 1::2] -= curv[1]
    band[kd - 1, 1::2] -= curv[2]
    return band


def _positive_definite(ab: np.ndarray) -> bool:
    from scipy.linalg.lapack import dpbtrf
    _, info = dpbtrf(ab)
    return info == 0


def _flat_shapes():
    from .geometry import Workplane
    return (Workplane,)


_FLAT_SHAPES = _flat_shapes()
