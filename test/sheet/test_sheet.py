"""Verification of the sheet model against exact equilibria and closed forms."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.sheet.analytic import elastic_chain_equilibrium
from rheo_shaping.sheet.geometry import Cake, Workplane
from rheo_shaping.sheet.polygon import RoundedConvexPolygon
from rheo_shaping.sheet.chain import ChainConstants, Obstacle, SheetModel
from rheo_shaping.sheet.simulation import settle

G = 9.81
EA = 95.0 * 0.1          # N: k1 times the specimen length (paper's fondant)


def elastic_chain(n: int, span=0.10, drop=-0.08, length=0.15, mu=0.3125):
    """A purely elastic chain (c2 = inf) between two fixed points."""
    L = np.full(n + 1, length / (n + 1))
    return ChainConstants(
        anchor_top=np.array([0.0, 0.0]), anchor_bottom=np.array([span, drop]),
        rest_length=L, k1=EA / L, c1=np.zeros(n + 1), c2=np.full(n + 1, np.inf),
        mass=np.full(n, mu * length / (n + 1)), radius=2e-3, gravity=G)


def straight_start(c: ChainConstants) -> np.ndarray:
    s = np.linspace(0.0, 1.0, c.n_masses + 2)[1:-1, None]
    return c.anchor_top + s * (c.anchor_bottom - c.anchor_top)


@pytest.mark.parametrize("n", [5, 24, 60])
def test_settled_elastic_chain_matches_exact_discrete_equilibrium(n):
    c = elastic_chain(n)
    model = SheetModel(c, [], force_tol=1e-11)
    exact = elastic_chain_equilibrium(
        c.anchor_top, c.anchor_bottom, c.rest_length, c.k1, c.mass, G)
    # a straight start shorter than the rest length: links start slack
    state = settle(model, straight_start(c), duration=0.5, dt=2e-3)
    for _ in range(5):   # then quasi-static steps: no plastic flow, so it comes to rest
        state = model.step(state, 10.0)
    assert np.max(np.abs(state.x - exact)) < 1e-6
    # and the tension of every link equals the exact one
    T_exact = np.hypot(*np.diff(np.vstack((c.anchor_top, exact, c.anchor_bottom)), axis=0).T)
    T_exact = c.k1 * (T_exact - c.rest_length)
    assert np.allclose(state.tension, T_exact, rtol=0, atol=1e-6)


def single_link(k1, c1, c2, mass=2e-3, gravity=G):
    """One mass under an anchor: link 0 carries it, link 1 (to a second anchor) stays slack."""
    L0 = 0.01
    s = 0.1 / L0   # constants given on the 0.1 m specimen, scaled to the link
    return ChainConstants(
        anchor_top=np.array([0.0, 0.0]), anchor_bottom=np.array([0.0, 0.0]),
        rest_length=np.array([L0, 0.5]), k1=np.array([k1 * s, 1.0]),
        c1=np.array([c1 * s, 0.0]), c2=np.array([c2 * s, np.inf]),
        mass=np.array([mass]), radius=2e-3, gravity=gravity)


def creep_error(c1: float, dt: float, t_end: float = 20.0) -> float:
    """Largest error of the hanging link's elongation against Eq. 7-8, relative to its final
    value."""
    k1, c2 = 95.0, 1300.0
    c = single_link(k1, c1, c2)
    model = SheetModel(c, [], force_tol=1e-14)
    s = 0.1 / c.rest_length[0]
    kl, cl1, cl2 = k1 * s, c1 * s, c2 * s
    F = c.mass[0] * G
    state = model.initial_state(np.array([[0.0, -c.rest_length[0]]]))
    # the exact state at t = 0+: the Maxwell spring takes F at once; the dashpots flow at once
    v0 = F / cl2 + (F / cl1 if c1 > 0 else 0.0)
    state = replace(state, v=np.array([[0.0, -v0]]))
    if c1 == 0.0:
        state = replace(state, e1=np.array([F / kl, 0.0]),
                        x=np.array([[0.0, -c.rest_length[0] - F / kl]]))
    worst = 0.0
    for k in range(1, int(round(t_end / dt)) + 1):
        state = model.step(state, dt)
        t = k * dt
        elong = -state.x[0, 1] - c.rest_length[0]
        kelvin = F / kl * (1.0 - np.exp(-kl * t / cl1)) if c1 > 0 else F / kl
        worst = max(worst, abs(elong - (F * t / cl2 + kelvin)))
    # the mass has inertia, which Eq. 7-8 neglect: m a ~ 1e-7 F while the Kelvin creep slows
    assert state.tension[0] == pytest.approx(F, rel=1e-9 if c1 == 0.0 else 1e-6)
    return worst / (F * t_end / cl2 + F / kl)


@pytest.mark.parametrize("dt", [0.05, 1.0, 5.0])
def test_maxwell_link_under_constant_force_creeps_exactly_as_eq_7_8(dt):
    """Constant force on a Maxwell link: elongation F/k1 + F t/c2, exact at any step."""
    assert creep_error(0.0, dt) < 1e-9


def test_three_element_link_under_constant_force_converges_to_eq_7_8():
    """c1 > 0: nothing jumps at t = 0, but the elongation is curved within a step while the
    step law takes the c1 force at the step's mean rate: first order in dt, unconditionally
    stable (docs/model.md)."""
    e1, e2, e3 = (creep_error(300.0, dt) for dt in (0.04, 0.02, 0.01))
    assert e3 < 3e-4
    assert 1.8 < e1 / e2 < 2.2 and 1.8 < e2 / e3 < 2.2


@pytest.mark.parametrize("c1", [0.0, 300.0])
def test_link_pulled_at_constant_rate_follows_eq_5(c1):
    """A tool pushes the mass away from the anchor at v: F = c2 v (1 - c2/(c1+c2) exp(-k1
    t/(c1+c2)))."""
    k1, c2, v = 95.0, 1300.0, 1e-3
    c = single_link(k1, c1, c2, mass=1e-6, gravity=0.0)
    tool = RoundedConvexPolygon.circle(0.005)
    # contact stiffness: compliance in series 1e-6 of the link's, round-off ~1e-9 N
    model = SheetModel(c, [Obstacle("tool", tool, moving=True)], contact_stiffness=1e9,
                       force_tol=1e-12)
    L0 = c.rest_length[0]
    x0 = np.array([[L0, 0.0]])
    reach = c.radius + 0.005      # the tool sits between the anchor and the mass, touching it
    state = replace(model.initial_state(x0, tool=(L0 - reach, 0.0)), v=np.array([[v, 0.0]]))
    s = 0.1 / L0
    kl, cl1, cl2 = k1 * s, c1 * s, c2 * s
    dt = 0.1
    for k in range(1, 201):
        t = k * dt
        state = model.step(state, dt, tool=(L0 - reach + v * t, 0.0))
        F_exact = cl2 * v * (1.0 - cl2 / (cl1 + cl2) * np.exp(-kl * t / (cl1 + cl2)))
        # the penalty contact is a spring in series: relative error S/K_c, with the link's step
        # stiffness S ~ k1 (Maxwell: 1e-6) or ~ c1/dt (three-element: 3e-5)
        bound = 2.0 * (kl + cl1 / dt) / 1e9
        assert state.tension[0] == pytest.approx(F_exact, rel=bound), t
        assert state.contact[0, 0, 0] == pytest.approx(state.tension[0], rel=1e-7)


@pytest.mark.parametrize("tool_kind", ["corner_wrap", "flat_pinch"])
def test_tool_pushing_sheet_against_wall_is_frictionless_and_balanced(tool_kind):
    """Elastic sheet pushed onto the cake wall by a tool: no penetration, normal forces,
    balance."""
    from rheo_shaping.params.cell import CellParams
    from rheo_shaping.sheet.simulation import build_chain
    p = CellParams()
    p = replace(p, material=replace(p.material, c2=float("inf")))
    c, x0 = build_chain(p)
    r = c.radius
    cake = Cake(p.cake.height, p.cake.fillet_radius, p.cake.radius)
    if tool_kind == "corner_wrap":
        # face 0.5 mm further from the wall than a sheet thickness: the tool's corner wraps the
        # sheet
        tool = RoundedConvexPolygon.rounded_rectangle(0.02, 0.04, 0.008)
        end = np.array([0.01 + 2 * r + 5e-4, 0.045])
    else:
        # the flat face squeezes the sheet onto the wall by 0.2 um: about 1 N on each sphere
        tool = RoundedConvexPolygon.rounded_rectangle(0.02, 0.04, 0.008)
        end = np.array([0.01 + 2 * r - 2e-7, 0.045])
    model = SheetModel(c, [Obstacle("cake", cake), Obstacle("workplane", Workplane()),
                           Obstacle("tool", tool, moving=True)], force_tol=1e-10)
    start = np.array([0.06, end[1]])
    state = settle(model, x0, 0.3, 2e-3, tool=start)
    for s in np.linspace(0.0, 1.0, 201)[1:]:
        state = model.step(state, 0.25, start + s * (end - start))
    for _ in range(20):
        state = model.step(state, 100.0, end)
    touching_tool = np.hypot(*state.contact[2].T) > 0
    touching_cake = np.hypot(*state.contact[0].T) > 0
    assert touching_tool.sum() >= 2 and touching_cake.sum() >= 3
    if tool_kind == "flat_pinch":
        pinched = touching_tool & touching_cake
        assert pinched.any()
        assert np.max(np.abs(state.contact[2, pinched, 0])) > 0.1   # a real squeeze, N
    # no penetration beyond 1e-5 m
    for ob, off in ((cake, (0, 0)), (Workplane(), (0, 0)), (tool, end)):
        d, _ = ob.signed_distance(state.x, off)
        assert np.min(d) > r - 1e-5
    # frictionless: every contact force is along the surface normal
    for ob, off, f in ((cake, (0, 0), state.contact[0]), (tool, end, state.contact[2])):
        _, n = ob.signed_distance(state.x, off)
        tangential = f[:, 0] * n[:, 1] - f[:, 1] * n[:, 0]
        assert np.max(np.abs(tangential)) < 1e-12
        assert np.all(np.einsum("ij,ij->i", f, n) >= 0.0)   # pushes, never pulls
    # force balance of the whole chain: gravity + contacts + bond reactions = 0
    nodes = model.nodes(state.x)
    u = np.diff(nodes, axis=0)
    u /= np.hypot(*u.T)[:, None]
    bonds = -state.tension[0] * u[0] + state.tension[-1] * u[-1]
    total = state.contact.sum(axis=(0, 1)) + bonds - np.array([0.0, G * c.mass.sum()])
    assert np.max(np.abs(total)) < 1e-6
    # and of every mass
    f_links = state.tension[:, None] * u
    per_mass = state.contact.sum(
        axis=0) - f_links[:-1] + f_links[1:] - np.c_[np.zeros(c.n_masses), G * c.mass]
    assert np.max(np.abs(per_mass)) < 1e-6


def test_slack_links_carry_no_force_and_do_not_flow():
    """A chain longer than the distance between its bonds, lying on the workplane, is slack."""
    n = 10
    L = np.full(n + 1, 0.01)
    c = ChainConstants(np.array([0.0, 2e-3]), np.array([0.05, 2e-3]), L, 950.0 * np.ones(n + 1),
                       np.zeros(n + 1), 13000.0 * np.ones(n + 1), np.full(n, 2e-3), 2e-3, G)
    model = SheetModel(c, [Obstacle("workplane", Workplane())])
    x0 = np.c_[np.linspace(0.005, 0.045, n), np.full(n, 2e-3)]
    state = model.initial_state(x0)
    for _ in range(10):
        state = model.step(state, 1.0)
    assert np.all(state.tension == 0.0)
    assert np.all(state.p <= 1e-15)
    d, _ = Workplane().signed_distance(state.x)
    assert np.min(d) > c.radius - 1e-5


def test_settle_time_zero_starts_from_the_undeformed_drape():
    """solver.settle_time 0 lies inside its range [0, 3600] s: the run starts from the
    undeformed drape (no sag), it does not divide by zero (issue 27, fuzz of bounds)."""
    from dataclasses import replace as _replace

    from rheo_shaping.params.cell import CellParams
    from rheo_shaping.sheet.simulation import Simulation
    cell = CellParams()
    cell = _replace(cell, solver=_replace(cell.solver, settle_time=0.0))
    sim = Simulation(cell, tool_start=(0.1, 0.2))
    st = sim.state
    assert st.t == 0.0 and np.all(np.isfinite(st.x))
    assert np.allclose(st.x, sim.model.initial_state(sim.x0, st.tool).x)
