"""The dynamic world: the cell as a chain of masses with inertia, laid and released at t = 0.

An independent simulator of the same cell as :mod:`rheo_shaping.sheet` (none of
its code): point masses on three-element links (paper Eq. 2, backward Euler
per step), a soft penalty contact with damping and Coulomb friction (stick
springs that slip at mu F_n) on cake, workplane and tool, air damping, gravity,
and the sheet laid in a drawn shape (:class:`~rheo_shaping_validation.worlds.params.LayParams`)
and released from rest when the process starts, so it falls, settles and creeps
onto the mould while the tool approaches.  The compiled step is
:mod:`rheo_shaping_validation.worlds.kernel`.

Effects: the library's (``CellParams.effects``: friction_mould, friction_tool,
bending, kelvin_c1, power_law, thinning, tool_offset, mass_error) and the
world's own (:class:`~rheo_shaping_validation.worlds.params.WorldEffects`).  Its form's variations
(:class:`~rheo_shaping_validation.worlds.forms.FormParams`, all off by default): the release swept
along the sheet, a soft mould and a soft tool pad, a hand-rolled thickness, the damping.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from rheo_shaping.params.cell import CellParams
from . import kernel as K
from .forms import FormParams, thickness_profile
from .params import LayParams, WorldEffects, WorldNumerics


# ------------------------------------------------------------------ the laid sheet
def _polyline_length(pts: np.ndarray) -> float:
    return float(np.hypot(*np.diff(pts, axis=0).T).sum())


def _at_arc(pts: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points of polyline ``pts`` at arc lengths ``s`` [m]."""
    cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))))
    return np.c_[np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])]


def scenario_length(p: CellParams) -> float:
    """The sheet's rest length [m] as the scenario gives it: flat on the top from the bond,
    round the edge (radius fillet + r) to where a straight line to the workplane bond
    leaves it, that chord, and ``sheet.excess_length``."""
    s, c = p.sheet, p.cake
    r = 0.5 * s.thickness
    rho = c.fillet_radius + r
    centre = np.array([-c.fillet_radius, c.height - c.fillet_radius])
    bottom = np.array([s.bottom_bond_x, r])
    q = bottom - centre
    dist = float(np.hypot(*q))
    theta = min(math.atan2(q[1], q[0]) + math.acos(rho / dist), 0.5 * math.pi)
    leave = centre + rho * np.array([math.cos(theta), math.sin(theta)])
    return float(-c.fillet_radius - s.top_bond_x + rho * (0.5 * math.pi - theta)
                 + np.hypot(*(bottom - leave)) + s.excess_length)


def laid_shape(p: CellParams, lay: LayParams, tool=None, tilt: float = 0.0,
               n_fine: int = 1500) -> np.ndarray:
    """The laid centreline (M, 2) [m] from the top bond to the workplane bond, of the
    scenario's length (:func:`scenario_length`): flat on the top (raised by ``lay.lift``
    after a short ramp), round the edge, and the free part sagging under its chord by
    w(u) = A (sin(pi u) + mode2 sin(2 pi u)) (downward, A solved for the length), kept out
    of cake, workplane and the tool (reference point at ``tool`` [m], or no tool)."""
    s, c = p.sheet, p.cake
    r = 0.5 * s.thickness
    rho = c.fillet_radius + r + lay.lift
    centre = np.array([-c.fillet_radius, c.height - c.fillet_radius])
    top = np.array([s.top_bond_x, c.height + r])
    bottom = np.array([s.bottom_bond_x, r])
    q = bottom - centre
    dist = float(np.hypot(*q))
    if dist <= rho:
        raise ValueError(f"workplane bond {bottom.tolist()} lies inside the rounded edge")
    theta = min(math.atan2(q[1], q[0]) + math.acos(rho / dist), 0.5 * math.pi)
    ramp = min(5e-3, 0.5 * (-c.fillet_radius - top[0]))
    flat = np.array([top, [top[0] + ramp, top[1] + lay.lift],
                     [-c.fillet_radius, top[1] + lay.lift]])
    th = np.linspace(0.5 * math.pi, theta, 200)
    arc = centre + rho * np.c_[np.cos(th), np.sin(th)]
    p0 = arc[-1]
    head = np.vstack((flat, arc[1:]))
    target = scenario_length(p) - _polyline_length(head)
    chord = bottom - p0
    if target < float(np.hypot(*chord)) - 1e-12:
        raise ValueError("the scenario's sheet is too short to reach the workplane bond")
    u = np.linspace(0.0, 1.0, n_fine)
    shape = np.sin(np.pi * u) + lay.mode2 * np.sin(2.0 * np.pi * u)
    base = p0 + u[:, None] * chord
    par = np.zeros(K.N_PAR)
    par[K.I_CAKE_H], par[K.I_FILLET], par[K.I_RADIUS] = c.height, c.fillet_radius, r
    verts, rad = tool_vertices(p, tilt)
    par[K.I_TOOL_R] = rad

    def free(a: float) -> np.ndarray:
        pts = base.copy()
        pts[:, 1] -= a * shape
        if tool is None:
            return K.push_out(pts, par, verts, 0.0, 0.0, False)
        return K.push_out(pts, par, verts, float(tool[0]), float(tool[1]), True)

    lo, hi = 0.0, 2.0 * float(np.hypot(*chord))
    for _ in range(40):                                # length rises with A: bisection
        mid = 0.5 * (lo + hi)
        if _polyline_length(free(mid)) < target:
            lo = mid
        else:
            hi = mid
    return np.vstack((head, free(0.5 * (lo + hi))[1:]))


def tool_vertices(p: CellParams, tilt: float = 0.0) -> tuple[np.ndarray, float]:
    """The tool's polygon (K, 2) [m] (CCW, about its reference point, rotated by ``tilt``
    [rad]) and its rounding radius [m]."""
    t = p.tool
    if t.shape == "circle":
        v, rad = np.zeros((1, 2)), t.radius
    elif t.shape == "rounded_rectangle":
        a, b = 0.5 * t.width - t.corner_radius, 0.5 * t.height - t.corner_radius
        v, rad = np.array([[-a, -b], [a, -b], [a, b], [-a, b]]), t.corner_radius
    else:
        v, rad = np.asarray(t.vertices, float).reshape(-1, 2), t.corner_radius
    c, s = math.cos(tilt), math.sin(tilt)
    return np.ascontiguousarray(v @ np.array([[c, s], [-s, c]])), float(rad)


# ------------------------------------------------------------------ the run
@dataclass
class WorldRun:
    """Samples of a world run (k at ``t[k]``): the same attributes the measurement reads."""

    t: np.ndarray            # (K,) s
    x: np.ndarray            # (K, N, 2) m
    tension: np.ndarray      # (K, N+1) N, mean over the sample's interval
    plastic: np.ndarray      # (K, N+1) m
    tool: np.ndarray         # (K, 2) m, the commanded tool reference point
    tool_force: np.ndarray   # (K, 2) N, sheet on the tool (mean over the interval)
    mould_force: np.ndarray  # (K, 2) N, sheet on cake and workplane
    rest_length: np.ndarray  # (N+1,) m
    anchors: tuple           # the bonds, (2,) m each
    wall_time_s: float
    params: CellParams = field(repr=False)
    steps: int = 0               # time steps taken
    unconverged_steps: int = 0   # steps that used every Newton solve (kernel.MAX_NEWTON)

    def nodes(self, k: int = -1) -> np.ndarray:
        """Bond, masses, bond (N+2, 2) [m] at sample ``k``."""
        return np.vstack((self.anchors[0], self.x[k], self.anchors[1]))

    @property
    def F_max(self) -> float:
        """Largest link tension [N] over the run (Table 2's F_max)."""
        return float(self.tension.max())

    def tool_touches(self, threshold: float = 1e-3) -> np.ndarray:
        """(K,) bool: the sheet pushes the tool by more than ``threshold`` [N]."""
        return np.hypot(*self.tool_force.T) > threshold


def step_schedule(nm: WorldNumerics, t_end: float, pitch: float) -> tuple[np.ndarray, np.ndarray]:
    """The steps (S,) [s] of a run to ``t_end`` [s] and which of them end a sample (S,) bool.

    Steps of ``dt`` (``dt_release`` for the first ``release_time``), both scaled by
    pitch / ``reference_pitch`` when the chain is finer than the reference (the links'
    vibration period falls with the pitch); whole steps per sample interval."""
    shrink = min(1.0, pitch / nm.reference_pitch)
    interval = 1.0 / nm.output_rate
    n_out = int(math.ceil(t_end * nm.output_rate - 1e-9))
    hs, keep = [], []
    for k in range(n_out):
        fine = k * interval < nm.release_time
        n = max(1, int(math.ceil(interval / ((nm.dt_release if fine else nm.dt) * shrink) - 1e-9)))
        hs.append(np.full(n, interval / n))
        kk = np.zeros(n, dtype=bool)
        kk[-1] = True
        keep.append(kk)
    return np.concatenate(hs), np.concatenate(keep)


def run_world(params: CellParams, path, t_end: float | None = None,
              lay: LayParams = LayParams(), extra: WorldEffects = WorldEffects(),
              numerics: WorldNumerics = WorldNumerics(),
              form: FormParams = FormParams()) -> WorldRun:
    """Release the laid sheet at t = 0 and run the tool on ``path`` (``position(t)`` [m],
    the commanded reference point) to ``t_end`` [s] (default the process time), in the
    world's ``form`` (its variations, :mod:`~rheo_shaping_validation.worlds.forms`; default: none).

    Raises RuntimeError when the step fails (not positive definite, non-finite)."""
    t_end = params.movement.process_time if t_end is None else float(t_end)
    nm = numerics
    if form.damping_scale != 1.0:
        nm = replace(nm, air_damping=nm.air_damping * form.damping_scale,
                     contact_damping=nm.contact_damping * form.damping_scale)
    s, mat, eff = params.sheet, params.material, params.effects
    if eff.friction_mould > 0.0 or eff.friction_tool > 0.0:
        nm = replace(nm, dt=min(nm.dt, nm.dt_friction))     # the stick springs converge
    line = laid_shape(params, lay, np.asarray(path.position(0.0), float)
                      + np.asarray(eff.tool_offset, float), extra.tool_tilt)
    total = _polyline_length(line)
    nodes = _at_arc(line, np.linspace(0.0, total, nm.n_masses + 2))
    nodes[0], nodes[-1] = line[0], line[-1]
    laid = np.hypot(*np.diff(nodes, axis=0).T)
    L0 = laid / (1.0 + lay.prestrain)
    scale = mat.specimen_length / L0                      # k L_specimen / l (docs/paper.md)
    c2 = mat.c2 if math.isfinite(mat.c2) else 1e30
    k1 = mat.k1 * scale
    c1 = (mat.c1 + eff.kelvin_c1) * scale
    c2 = c2 * scale
    mass = s.mass_per_length * (1.0 + eff.mass_error) * 0.5 * (L0[:-1] + L0[1:])
    if form.thickness_variation != 0.0:
        # a hand-rolled sheet: each link's cross-section, hence its k1, c1, c2 and mass,
        # scale with its relative thickness (mean 1)
        tau = thickness_profile(form, L0.size)
        k1, c1, c2 = k1 * tau, c1 * tau, c2 * tau
        mass = (s.mass_per_length * (1.0 + eff.mass_error) * 0.5
                * (tau[:-1] * L0[:-1] + tau[1:] * L0[1:]))
    pitch = float(L0.mean())
    kc = nm.contact_modulus * pitch
    cn = 2.0 * nm.contact_damping * math.sqrt(kc * float(mass.mean()))
    hs, keep = step_schedule(nm, t_end, pitch)
    par = np.zeros(K.N_PAR)
    par[K.I_GRAV] = params.solver.gravity
    par[K.I_KC] = kc
    par[K.I_CN] = cn
    par[K.I_KT] = nm.stick_ratio * kc
    par[K.I_MU_MOULD] = eff.friction_mould
    par[K.I_MU_TOOL] = eff.friction_tool
    par[K.I_AIR] = nm.air_damping
    par[K.I_CAKE_H] = params.cake.height
    par[K.I_FILLET] = params.cake.fillet_radius
    par[K.I_RADIUS] = 0.5 * s.thickness
    verts, rad = tool_vertices(params, extra.tool_tilt)
    par[K.I_TOOL_R] = rad
    par[K.I_EI] = eff.bending
    par[K.I_PL_N] = eff.power_law
    par[K.I_PL_REF] = eff.power_law_ref_tension
    par[K.I_THIN] = eff.thinning
    par[K.I_HARD] = extra.strain_hardening
    par[K.I_ADH] = extra.adhesion
    par[K.I_ADH_RANGE] = extra.adhesion_range
    par[K.I_LET_GO] = lay.let_go
    par[K.I_SOFT_MOULD] = form.mould_softness
    par[K.I_SOFT_TOOL] = form.tool_softness
    par[K.I_SWEEP] = form.release_sweep
    # the tool path sampled at 100 Hz; the real tool is off the commanded by tool_offset
    span = float(hs.sum())
    tool_t = np.linspace(0.0, span, int(math.ceil(span * 100.0)) + 1)
    commanded = np.array([path.position(t) for t in tool_t], dtype=float)
    lagged = np.array([path.position(max(t - extra.tool_lag, 0.0)) for t in tool_t], dtype=float)
    real = lagged + np.asarray(eff.tool_offset, float)          # the tool's real pose
    x = np.ascontiguousarray(nodes[1:-1].copy())
    v = np.zeros_like(x)
    e1 = np.zeros(L0.size)
    p = np.zeros(L0.size)
    anchors = np.ascontiguousarray(np.vstack((nodes[0], nodes[-1])))
    wall = time.perf_counter()
    t, xs, F, ftool, pl, fmould, status, unconverged = K.run_chain(
        x, v, anchors, L0, k1, c1, c2, mass, par, verts, tool_t, np.ascontiguousarray(real),
        hs, keep, e1, p)
    wall = time.perf_counter() - wall
    if status:
        why = "the step matrix is not positive definite" if status == 1 else "non-finite state"
        raise RuntimeError(f"dynamic world failed at t = {t[-1]:.3f} s: {why}")
    tool = np.c_[np.interp(t, tool_t, commanded[:, 0]), np.interp(t, tool_t, commanded[:, 1])]
    return WorldRun(t=t, x=xs, tension=F, plastic=pl, tool=tool, tool_force=ftool,
                    mould_force=fmould, rest_length=L0,
                    anchors=(anchors[0].copy(), anchors[1].copy()), wall_time_s=wall,
                    params=params, steps=int(hs.size), unconverged_steps=int(unconverged))
