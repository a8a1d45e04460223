"""The sheet: a chain of lumped masses joined by three-element links (Sec. 4.1).

N masses (spheres of radius ``r`` = half the sheet thickness) hang between
two fixed bonds and are joined by N + 1 links.  Link i joins node i-1 and
node i, where node -1 is the cake-top bond and node N the workplane bond.
Every link is a three-element unit with constants scaled to its rest length
(:mod:`rheo_shaping.material.three_element`); it carries tension only (a slack link buckles
and carries nothing).  Spheres touch the obstacles (cake, workplane, tool)
without friction and without interpenetration.

One time step is implicit (backward Euler in the positions, the exact
three-element update in the links).  Over a step the link force is affine in
the link length (:func:`rheo_shaping.material.three_element.step_coefficients`), so the new
positions minimise the incremental potential

    E(x) = sum m |x - x_pred|^2 / (2 dt^2) + sum 1/2 S (l - L*)_+^2
           + sum m g z + sum 1/2 K_c (r - d_obstacle(x))_+^2,

a convex function but for the contact terms.  ``x_pred = x + dt v`` with
inertia (``dynamic=True``), ``x_pred = x`` in the quasi-static regime where the
first term is only a tiny proximal regulariser (m/dt^2 ~ 1e-2 N/m against link
stiffnesses ~ 1e3 N/m).  Newton's method with a banded Cholesky solve and a
backtracking line search finds the minimiser; its Hessian is block
tridiagonal (half bandwidth 3, 4 with bending).  The whole step, effects
included, is one compiled kernel (:mod:`rheo_shaping.sheet.kernel`); this module
holds the data types and packs them for it.  The penalty stiffness K_c makes the largest
penetration F_contact / K_c (0.1 um per newton at the default 1e7 N/m).
See docs/model.md for why this formulation was chosen.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol, Sequence

import numpy as np

from . import kernel as _k


class Shape(Protocol):
    """What the sheet needs of an obstacle (see :mod:`rheo_shaping.sheet.geometry`)."""

    def signed_distance(self, points: np.ndarray,
                        offset=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        ...

    def kernel_description(self) -> tuple[int, float, np.ndarray]:
        """(kind, radius [m], vertices (K, 2) [m]) for
        :func:`rheo_shaping.sheet.kernel.shape_eval`."""
        ...

    def outline(self, n_points: int) -> np.ndarray:
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
            raise ValueError(
                "mass must be a 1-D array of the N >= 1 sphere masses [kg], got shape "
                f"{np.shape(self.mass)}")
        _check_array("mass", self.mass, n, "kg", positive=True)
        _check_array("rest_length", self.rest_length, n + 1, "m", positive=True)
        _check_array("k1", self.k1, n + 1, "N/m", positive=True)
        _check_array("c1", self.c1, n + 1, "N s/m", positive=False)
        _check_array("c2", self.c2, n + 1, "N s/m", positive=True, allow_inf=True)
        for name in ("anchor_top", "anchor_bottom"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != (2,) or not np.all(np.isfinite(a)):
                raise ValueError(
                    f"{name} must be a finite point (x, z) [m], got {getattr(self, name)!r}")
        if not (np.isfinite(self.radius) and self.radius > 0.0):
            raise ValueError(f"radius = {self.radius!r} m is invalid: expected a finite value > 0")
        if not (np.isfinite(self.gravity) and self.gravity >= 0.0):
            raise ValueError(
                f"gravity = {self.gravity!r} m/s^2 is invalid: expected a finite value >= 0")

    @property
    def n_masses(self) -> int:
        return int(self.mass.shape[0])


@dataclass(frozen=True)
class SheetEffects:
    """Optional physics the nominal model leaves out (rheo_shaping.sheet.effects; all off by
    default).

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
    # m per step: slip within which friction acts as a stiff spring (stick)
    friction_slip: float = 1e-7

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


def _check_array(name: str, values, size: int, unit: str, positive: bool,
                 allow_inf: bool = False) -> None:
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


@dataclass
class StepRecord:
    """States after each of K steps (SheetModel.run_path): arrays over the steps first."""

    t: np.ndarray          # (K,) s
    x: np.ndarray          # (K, N, 2) m
    v: np.ndarray          # (K, N, 2) m/s
    e1: np.ndarray         # (K, N+1) m
    p: np.ndarray          # (K, N+1) m
    tension: np.ndarray    # (K, N+1) N
    contact: np.ndarray    # (K, n_obstacles, N, 2) N
    tool: np.ndarray       # (K, 2) m
    newton_iterations: np.ndarray   # (K,)
    error: Exception | None = None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def head(self, k: int) -> "StepRecord":
        """The first ``k`` steps."""
        return StepRecord(self.t[:k], self.x[:k], self.v[:k], self.e1[:k], self.p[:k],
                          self.tension[:k], self.contact[:k], self.tool[:k],
                          self.newton_iterations[:k], self.error)

    def state(self, k: int) -> "SheetState":
        """The state after step ``k`` (its own arrays)."""
        return SheetState(t=float(self.t[k]), x=self.x[k].copy(), v=self.v[k].copy(),
                          e1=self.e1[k].copy(), p=self.p[k].copy(),
                          tension=self.tension[k].copy(), contact=self.contact[k].copy(),
                          tool=self.tool[k].copy(),
                          newton_iterations=int(self.newton_iterations[k]))


class ConvergenceError(RuntimeError):
    """Newton's method did not converge in a step."""


class SheetModel:
    """Implicit stepping of a chain of masses with tension-only links and contact.

    ``stats`` counts the kernel's work since construction (see
    :data:`rheo_shaping.sheet.kernel.ST_NEWTON` and the other indices).
    """

    def __init__(self, constants: ChainConstants, obstacles: Sequence[Obstacle],
                 contact_stiffness: float = 1e7, force_tol: float = 1e-9,
                 max_newton: int = 50, effects: SheetEffects = SheetEffects()):
        self.c = constants
        self.effects = effects
        self.obstacles = tuple(obstacles)
        self.kc = float(contact_stiffness)
        self.force_tol = float(force_tol)
        self.max_newton = int(max_newton)
        self._n = constants.n_masses
        # how far a moving obstacle reaches from its reference point (skip it when farther)
        reach = [_reach(ob.shape) if ob.moving else np.inf for ob in self.obstacles]
        mu = [effects.mu(ob.name) for ob in self.obstacles]
        self._packed = _k.pack_model(constants, self.obstacles, reach, mu, self.kc,
                                     self.force_tol, effects)
        self.stats = np.zeros(5, dtype=np.int64)

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
        if not (np.isfinite(dt) and dt > 0.0):
            raise ValueError(f"time step dt = {dt!r} s is invalid: expected a finite value > 0")
        min_dt = dt / 256.0 if _min_dt is None else float(_min_dt)
        tool = np.array(tool, dtype=float).reshape(2)
        out = _k.advance(*self._state_args(state), tool, float(dt), bool(dynamic), min_dt,
                         *self._packed, self.max_newton, self.stats)
        return self._result(state.t + dt, out)

    def run_steps(self, state: SheetState, dt: float, n_steps: int, tool=(np.nan, np.nan),
                  dynamic: bool = True) -> SheetState:
        """``n_steps`` steps of ``dt`` [s] with the tool standing at ``tool`` [m], all in the
        kernel (the settle); the same steps as as many :meth:`step` calls."""
        if not (np.isfinite(dt) and dt > 0.0):
            raise ValueError(f"time step dt = {dt!r} s is invalid: expected a finite value > 0")
        tool = np.array(tool, dtype=float).reshape(2)
        x, v, e1, p, ten, con, prev = self._state_args(state)
        if not np.array_equal(prev, tool, equal_nan=True):   # first step moves the tool there
            state = self.step(state, dt, tool, dynamic)
            n_steps -= 1
            x, v, e1, p, ten, con, prev = self._state_args(state)
        if n_steps <= 0:
            return state
        out = _k.advance_fixed(x, v, e1, p, ten, con, tool, float(dt), int(n_steps),
                               bool(dynamic), *self._packed, self.max_newton, self.stats)
        return self._result(state.t + n_steps * dt, out)

    def run_path(self, state: SheetState, dts: np.ndarray, tools: np.ndarray,
                 dynamic: bool = True) -> "StepRecord":
        """Steps of ``dts`` (K,) [s], the tool ending step k at ``tools[k]`` (K, 2) [m], all
        in the kernel; the same steps as as many :meth:`step` calls.  The record holds
        every step's state; on a failed step it ends before it, and ``error`` holds the
        :class:`ConvergenceError` for the caller to raise once it kept the record."""
        dts = np.ascontiguousarray(dts, dtype=float).reshape(-1)
        tools = np.ascontiguousarray(tools, dtype=float).reshape(-1, 2)
        if dts.size and not (np.all(np.isfinite(dts)) and np.all(dts > 0.0)):
            bad = dts[~(np.isfinite(dts) & (dts > 0.0))][0]
            raise ValueError(f"time step dt = {bad!r} s is invalid: expected a finite value > 0")
        k, n, n_ob = dts.size, self._n, len(self.obstacles)
        rec = StepRecord(t=state.t + np.cumsum(dts) if k else np.zeros(0),
                         x=np.empty((k, n, 2)), v=np.empty((k, n, 2)), e1=np.empty((k, n + 1)),
                         p=np.empty((k, n + 1)), tension=np.empty((k, n + 1)),
                         contact=np.empty((k, n_ob, n, 2)), tool=tools.copy(),
                         newton_iterations=np.zeros(k, dtype=np.int64))
        if k:
            # the clock as step() keeps it: t + dt, step by step
            t = state.t
            for i in range(k):
                t = t + dts[i]
                rec.t[i] = t
            done, status, res = _k.advance_path(
                *self._state_args(state), dts, tools, bool(dynamic), *self._packed,
                self.max_newton, self.stats, rec.x, rec.v, rec.e1, rec.p, rec.tension,
                rec.contact, rec.newton_iterations)
            if done < k:
                rec = rec.head(done)
                rec.error = self._error(status, res)
        return rec

    def _error(self, status: int, res: float) -> ConvergenceError:
        if status == _k.NOT_SPD:   # pragma: no cover - the Hessian is SPD by construction
            return ConvergenceError("Newton system not positive definite (banded Cholesky)")
        return ConvergenceError(f"Newton did not converge in {self.max_newton} iterations "
                                f"(force residual {res:.3g} N)")

    @staticmethod
    def _state_args(state: SheetState) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                np.ndarray, np.ndarray, np.ndarray]:
        """The kernel's state arguments (x, v, e1, p, tension, contact, tool), contiguous."""
        c = np.ascontiguousarray
        return (c(state.x, dtype=float), c(state.v, dtype=float), c(state.e1, dtype=float),
                c(state.p, dtype=float), c(state.tension, dtype=float),
                c(state.contact, dtype=float), c(state.tool, dtype=float).reshape(2))

    def _result(self, t: float, out) -> SheetState:
        x, v, e1, p, ten, con, tool, iters, status, res = out
        if status != _k.OK:
            raise self._error(status, res)
        return SheetState(t=t, x=x, v=v, e1=e1, p=p, tension=ten, contact=con,
                          tool=tool, newton_iterations=int(iters))

    # ---------------------------------------------------------------- effects
    def _link_constants(self, state: SheetState):
        """k1, c1, c2 of the links over this step (thinning, power law: lagged on the state)."""
        fpar, links = self._packed[0], self._packed[1]
        x, v, e1, p, ten, con, tool = self._state_args(state)
        return _k.link_constants(links, e1, p, ten, fpar)

    def _bending_terms(self, x):
        """Energy [J], gradient (N, 2) [N] and per-mass EI/h^3 [N/m] of the bending term
        1/2 EI/h^3 |x_i-1 - 2 x_i + x_i+1|^2 (the kernel's)."""
        kb = self._packed[2][1]
        grad = np.zeros((self._n, 2))
        energy = _k.bending_terms(np.ascontiguousarray(x, dtype=float), kb,
                                  np.asarray(self.c.anchor_top, float),
                                  np.asarray(self.c.anchor_bottom, float), grad)
        return energy, grad, kb


#: :func:`_reach` of the shapes already measured (shapes are frozen, compared by value).
_REACH: dict = {}


def _reach(shape) -> float:
    """Largest distance [m] of a shape's outline from its reference point."""
    try:
        hit = _REACH.get(shape)
    except TypeError:                   # a shape that cannot be a key: measured every time
        hit, shape_key = None, None
    else:
        shape_key = shape
    if hit is not None:
        return hit
    outline = shape.outline(256)
    value = float(np.max(np.hypot(outline[:, 0], outline[:, 1])))
    if shape_key is not None:
        if len(_REACH) >= 64:
            _REACH.clear()
        _REACH[shape_key] = value
    return value
