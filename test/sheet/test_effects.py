"""The effects library (rheo_shaping.sheet.effects): closed forms where they exist, and each
effect moving the default process's outputs in the physically expected direction."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.sheet.effects import EFFECT_NAMES, EFFECTS, active_effects, nominal
from rheo_shaping.sheet.geometry import Workplane
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.sheet.chain import ChainConstants, Obstacle, SheetEffects, SheetModel
from rheo_shaping.sheet.paths import PolylinePath
from rheo_shaping.sheet.simulation import Simulation, build_chain, run_scenario

G = 9.81


@pytest.fixture(scope="module")
def base():
    return CellParams()


@pytest.fixture(scope="module")
def plan(base):
    return movement_plan(base)


@pytest.fixture(scope="module")
def nominal_run(base, plan):
    return run_scenario(base, plan)


def run_with(base, plan, name, values):
    return run_scenario(EFFECTS[name].apply(base, values), plan)


def test_registry_names_and_defaults_are_off(base):
    assert EFFECT_NAMES == ("friction_mould", "friction_tool", "bending", "kelvin_c1", "power_law",
                            "thinning", "tool_offset", "mass_error")
    assert active_effects(base) == []
    for name, e in EFFECTS.items():
        on = e.apply(base, [b[1] for b in e.realistic])
        assert active_effects(on) == [name]
        assert nominal(on) == base


def test_nominal_results_unchanged_by_the_effect_machinery(base, plan, nominal_run):
    """Every effect at its 'off' value gives the nominal run bit for bit."""
    for name, e in EFFECTS.items():
        r = run_scenario(e.apply(base, e.off), plan)
        assert r.F_max == nominal_run.F_max and r.delta == nominal_run.delta, name


# ------------------------------------------------------------------ tool_offset, mass_error,
# kelvin_c1
def test_tool_offset_equals_the_path_shifted_by_it(base, plan):
    shift = np.array([1.0e-3, 0.8e-3])
    knots = plan.knots()
    shifted = PolylinePath(knots, np.array([plan.position(t) + shift for t in knots]))
    unshifted = PolylinePath(knots, np.array([plan.position(t) for t in knots]))
    a = run_scenario(EFFECTS["tool_offset"].apply(base, tuple(shift)), unshifted)
    b = run_scenario(base, shifted)
    assert np.max(np.abs(a.x - b.x)) < 1e-12
    # the state keeps the commanded pose
    assert np.allclose(a.tool + shift, b.tool, atol=1e-15)
    assert abs(a.F_max - b.F_max) < 1e-12


def test_mass_error_and_kelvin_c1_scale_the_chain_constants(base):
    c0, _ = build_chain(base)
    c1, _ = build_chain(EFFECTS["mass_error"].apply(base, (0.25,)))
    assert np.allclose(c1.mass, 1.25 * c0.mass, rtol=1e-15)
    c2, _ = build_chain(EFFECTS["kelvin_c1"].apply(base, (400.0,)))
    assert np.allclose(c2.c1, 400.0 * base.material.specimen_length / c0.rest_length, rtol=1e-15)


def test_heavier_sheet_hangs_with_more_tension(base):
    """Gravity is the only load before the tool arrives: the settled tensions grow with the
    weight."""
    light = Simulation(base).state.tension
    heavy = Simulation(EFFECTS["mass_error"].apply(base, (0.3,))).state.tension
    assert np.max(heavy) > 1.2 * np.max(light)


# ------------------------------------------------------------------ friction: stick and slip
def block_on_workplane(mu: float):
    """One 20 g sphere on the workplane held by a stretched link to the left (slack to the
    right)."""
    r, k = 2e-3, 10.0
    c = ChainConstants(anchor_top=np.array([-0.05, r]), anchor_bottom=np.array([0.05, r]),
                       rest_length=np.array([0.04, 0.06]), k1=np.array([k, k]), c1=np.zeros(2),
                       c2=np.full(2, np.inf), mass=np.array([0.02]), radius=r, gravity=G)
    model = SheetModel(c, [Obstacle("workplane", Workplane())], 1e7, 1e-10, 100,
                       SheetEffects(friction=(("workplane", mu),)))
    st = model.initial_state(np.array([[0.0, r - 0.02 * G / 1e7]]))
    st = replace(st, contact=np.array([[[0.0, 0.02 * G]]]))        # resting on the plane
    return model, st, k


def test_friction_sticks_below_mu_N():
    model, st, k = block_on_workplane(mu=0.8)          # pull 0.1 N < 0.8 x 0.196 N
    for _ in range(10):
        st = model.step(st, 0.5, dynamic=False)
    # sticks: < 1e-7 m of regularised creep per step
    assert abs(st.x[0, 0]) < 1e-6
    friction = st.contact[0, 0, 0]
    assert friction == pytest.approx(k * 0.01, rel=1e-3)  # holds the whole pull


def test_friction_slides_until_the_pull_equals_mu_N():
    mu = 0.3
    model, st, k = block_on_workplane(mu)
    for _ in range(2):
        st = model.step(st, 0.5, dynamic=False)
    pull = k * (np.hypot(*(st.x[0] - model.c.anchor_top)) - 0.04)
    # Coulomb: it slides until the pull equals mu N (then creeps < 0.1 % per step near the limit,
    # the price of the regularised stick, docs/model.md)
    assert pull == pytest.approx(mu * 0.02 * G, rel=5e-3)
    assert st.x[0, 0] == pytest.approx(-0.01 + mu * 0.02 * G / k, abs=1e-4)
    assert st.contact[0, 0, 0] == pytest.approx(pull, rel=1e-3)   # friction balances the link


# ------------------------------------------------------------------ bending
def test_bending_energy_of_a_polygon_is_EI_L_over_2R2():
    EI, R, n = 2e-5, 0.05, 40
    phi = np.linspace(0.0, 0.6, n + 2)
    pts = R * np.c_[np.cos(phi), np.sin(phi)]
    h = np.hypot(*(pts[1] - pts[0]))
    c = ChainConstants(anchor_top=pts[0], anchor_bottom=pts[-1], rest_length=np.full(n + 1, h),
                       k1=np.full(n + 1, 1e3), c1=np.zeros(n + 1), c2=np.full(n + 1, np.inf),
                       mass=np.full(n, 1e-3), radius=1e-3)
    model = SheetModel(c, [], effects=SheetEffects(bending=EI))
    energy, grad, _ = model._bending_terms(pts[1:-1])
    theta = phi[1] - phi[0]
    exact = n * 0.5 * EI / h ** 3 * (2 * h * np.sin(theta / 2)) ** 2 * \
        (2 * np.sin(theta / 2) / theta) ** 0
    assert energy == pytest.approx(n * 0.5 * EI / h ** 3 *
                                   (4 * R * np.sin(theta / 2) ** 2) ** 2, rel=1e-12)
    assert energy == pytest.approx(EI * n * h / (2 * R ** 2),
                                   rel=2e-3)      # continuum EI L / (2 R^2)
    assert exact > 0
    # gradient by central differences
    x = pts[1:-1].copy()
    for i, j in ((3, 0), (17, 1), (n - 1, 0)):
        e = np.zeros_like(x)
        e[i, j] = 1e-7
        fd = (model._bending_terms(x + e)[0] - model._bending_terms(x - e)[0]) / 2e-7
        assert fd == pytest.approx(grad[i, j], rel=1e-5, abs=1e-12)


def test_bending_stiffness_reduces_the_sag_of_a_span():
    """A strip between two pins at the same height sags less when it resists bending."""
    n, L = 15, 0.1
    xs = np.linspace(0.0, L, n + 2)
    c = ChainConstants(anchor_top=np.array([0.0, 0.1]), anchor_bottom=np.array([L, 0.1]),
                       rest_length=np.full(n + 1, L / (n + 1)), k1=np.full(n + 1, 2e3),
                       c1=np.zeros(n + 1), c2=np.full(n + 1, np.inf), mass=np.full(n, 2e-3),
                       radius=1e-3)
    sags = []
    for EI in (0.0, 2e-3):
        model = SheetModel(c, [], 1e7, 1e-10, 100, SheetEffects(bending=EI))
        st = model.initial_state(np.c_[xs[1:-1], np.full(n, 0.1)])
        for _ in range(30):
            st = model.step(st, 1.0, dynamic=False)
        sags.append(0.1 - st.x[:, 1].min())
    assert sags[1] < 0.7 * sags[0]


# ------------------------------------------------------------------ rheology: power law, thinning
def test_power_law_dashpot_rate_closed_form(base):
    """c2_eff = c2 (F / F_ref)^(1 - 1/n): the creep rate (F/c2)(F/F_ref)^(1/n - 1) (lagged on
    F)."""
    sim = Simulation(EFFECTS["power_law"].apply(base, (0.6,)))
    st = sim.state
    k1, c1, c2 = sim.model._link_constants(st)
    F = np.maximum(st.tension, 1e-3 * 0.5)
    assert np.allclose(c2, sim.constants.c2 * (F / 0.5) ** (1 - 1 / 0.6), rtol=1e-14)
    at_ref = replace(st, tension=np.full_like(st.tension, 0.5))
    assert np.allclose(sim.model._link_constants(at_ref)[2], sim.constants.c2, rtol=1e-14)


def test_thinning_scales_the_links_by_L_over_L_plus_p(base):
    sim = Simulation(EFFECTS["thinning"].apply(base, (1.5,)))
    st = replace(sim.state, p=np.full_like(sim.state.p, 2e-3))
    k1, c1, c2 = sim.model._link_constants(st)
    L = sim.constants.rest_length
    assert np.allclose(k1, sim.constants.k1 * (L / (L + 2e-3)) ** 1.5, rtol=1e-14)
    assert np.allclose(c2, sim.constants.c2 * (L / (L + 2e-3)) ** 1.5, rtol=1e-14)


# ------------------------------------------------------------------ directions in the default
# process
def test_directions_in_the_default_process(base, plan, nominal_run):
    F0, D0 = nominal_run.F_max, nominal_run.delta
    p0 = nominal_run.plastic[-1].sum()
    # a dashpot parallel to k1 resists the stretch rate: more force for the same tool path
    assert run_with(base, plan, "kelvin_c1", (1000.0,)).F_max > 1.1 * F0
    # below F_ref (all of settling) a shear-thinning dashpot flows more slowly: more tension builds
    # up
    pl = run_with(base, plan, "power_law", (0.6,))
    assert pl.F_max > F0
    # thinning softens the stretched links: less force, more plastic flow
    th = run_with(base, plan, "thinning", (1.0,))
    assert th.F_max < F0 and th.plastic[-1].sum() > p0
    # friction on the tool resists the sheet sliding over it: more tension near the tool
    assert run_with(base, plan, "friction_tool", (0.4,)).F_max > F0
    # friction on the mould holds the sheet on the cake: less of it is drawn down, larger gap
    # (by more than twice the 0.1 mm discretisation tolerance of Delta)
    assert run_with(base, plan, "friction_mould", (0.4,)).delta > D0 + 0.25e-3
    # a stiff sheet does not follow the tool into the corner: larger gap
    assert run_with(base, plan, "bending", (4e-6,)).delta > D0 + 0.5e-3
    # a heavier sheet: more tension
    assert run_with(base, plan, "mass_error", (0.3,)).F_max > F0
    # the tool sits 1 mm farther from the wall than commanded: the gap at the foot grows by about
    # that
    off = run_with(base, plan, "tool_offset", (1e-3, 0.0))
    assert off.delta - D0 == pytest.approx(1e-3, abs=0.5e-3)
