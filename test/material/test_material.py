"""Material models: exact stepped responses against closed forms, scaling, validation.

The references are closed forms written out here or in closed_forms.py (the
paper's Eq. 3-11), and, for the closed forms themselves, a tight numerical
integration of the model ODEs: never our own stepping.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from rheo_shaping.material import closed_forms as cf
from rheo_shaping.material.burgers import (
    Burgers,
    burgers_creep,
    burgers_creep_recovery,
    burgers_elongation_step,
    burgers_tensile_force,
)
from rheo_shaping.material.three_element import (ThreeElement, elongation_step, maxwell,
                                                 step_coefficients)
from rheo_shaping.material.response import elongation_response, force_response

V = 1e-3                        # pull speed of the paper [m/s]
PAPER = maxwell(95.0, 1.30e3)   # paper Sec. 3.4 on the 0.1 m specimen
THREE = ThreeElement(95.0, 300.0, 1.30e3)
BURG = Burgers(95.0, 300.0, 1.30e3, 150.0)
BURG_C1_0 = Burgers(95.0, 0.0, 1.30e3, 150.0)
MATERIALS = {"maxwell": PAPER, "three-element": THREE, "burgers": BURG, "burgers-c1=0": BURG_C1_0}
STEPS = (0.01, 0.5, 3.7, 25.0, 100.0)      # s; the largest exceed every time constant


def _tensile_reference(m, t):
    if isinstance(m, Burgers):
        return burgers_tensile_force(m, t, V)
    return cf.tensile_force(m, t, V)


def _creep_reference(m, t, F, t1):
    if isinstance(m, Burgers):
        return burgers_creep_recovery(m, t, F, t1)
    return cf.creep_recovery(m, t, F, t1)


def _j2(m):
    return m.j2 if isinstance(m, Burgers) else 0.0


# --------------------------------------------------------------- paper facts
def test_paper_constants_give_the_paper_b_and_c2():
    # Eq. 13: b = k1/(c1+c2) = 73.1e-3 1/s for k1 = 95.0, c1 = 0, c2 = 1.30e3
    assert PAPER.k1 / (PAPER.c1 + PAPER.c2) == pytest.approx(73.1e-3, rel=1e-3)
    # Eq. 10 with Table 1's mean: c2 = 0.5 * 60 / 23.1e-3 = 1.30e3
    assert cf.c2_from_creep_residual(0.5, 60.0, 23.1e-3) == pytest.approx(1.30e3, rel=1e-2)
    # Eq. 11: F(0) = 0 for the Maxwell model; Eq. 6: F_max = c2 v = 1.3 N
    assert cf.initial_force(PAPER, V) == 0.0
    assert cf.asymptotic_tensile_force(PAPER, V) == pytest.approx(1.3)


def test_eq5_is_eq3_through_F_equals_k1_x1_plus_c1_dx1():
    t = np.linspace(0.0, 80.0, 41)
    F = THREE.k1 * cf.kv_elongation(THREE, t, V) + THREE.c1 * cf.kv_rate(THREE, t, V)
    np.testing.assert_allclose(cf.tensile_force(THREE, t, V), F, rtol=1e-13)


def test_eq11_and_c1_inversion():
    F0 = cf.initial_force(THREE, V)
    assert F0 == pytest.approx(V * 1300 * 300 / 1600, rel=1e-13)
    assert cf.c1_from_initial_force(F0, THREE.c2, V) == pytest.approx(300.0, rel=1e-12)
    assert cf.c1_from_initial_force(-1e-3, THREE.c2, V) == 0.0


@pytest.mark.parametrize("m", [PAPER, THREE], ids=["maxwell", "three-element"])
def test_eq5_solves_the_ode_of_the_unit(m):
    # (c1 + c2) dx1/dt = c2 v - k1 x1 (Eq. 2), F = k1 x1 + c1 dx1/dt, integrated numerically
    sol = solve_ivp(lambda t, x: [(m.c2 * V - m.k1 * x[0]) / (m.c1 + m.c2)], (0, 60), [0.0],
                    t_eval=np.linspace(0.5, 60, 25), rtol=1e-12, atol=1e-16)
    x1 = sol.y[0]
    F = m.k1 * x1 + m.c1 * (m.c2 * V - m.k1 * x1) / (m.c1 + m.c2)
    np.testing.assert_allclose(cf.tensile_force(m, sol.t, V), F, rtol=1e-9)


def _burgers_ode(b, force_of_t=None, speed=None):
    """Right-hand side in (e2, e1, p); elongation- or force-driven."""
    def rhs(t, y):
        e2, e1, p = y
        if speed is not None:
            F = b.k2 * e2
            de1 = (F - b.k1 * e1) / b.c1
            dp = F / b.c2
            return [speed - de1 - dp, de1, dp]
        F = force_of_t(t)
        return [0.0, (F - b.k1 * e1) / b.c1, F / b.c2]
    return rhs


def test_burgers_tensile_closed_form_against_the_ode():
    b = BURG
    sol = solve_ivp(_burgers_ode(b, speed=V), (0, 80), [0, 0, 0], t_eval=np.linspace(0.2, 80, 40),
                    method="Radau", rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(burgers_tensile_force(b, sol.t, V), b.k2 * sol.y[0], rtol=1e-7)


def test_burgers_limits_are_three_element_and_series_maxwell():
    t = np.linspace(0.1, 90, 30)
    stiff = Burgers(95.0, 300.0, 1300.0, 1e12)
    np.testing.assert_allclose(burgers_tensile_force(stiff, t, V),
                               cf.tensile_force(THREE, t, V), rtol=1e-8)
    k = 95.0 * 150.0 / 245.0
    np.testing.assert_allclose(burgers_tensile_force(BURG_C1_0, t, V),
                               1300 * V * (1 - np.exp(-k * t / 1300)), rtol=1e-12)
    np.testing.assert_allclose(burgers_creep(BURG, t, 0.5),
                               0.5 / 150 + 0.5 * t / 1300 + 0.5 / 95 * (1 - np.exp(-95 * t / 300)),
                               rtol=1e-13)


# ------------------------------------------------- stepped exact responses
@pytest.mark.parametrize("dt", STEPS)
@pytest.mark.parametrize("name", list(MATERIALS))
def test_imposed_elongation_at_constant_speed_matches_closed_form(name, dt):
    m = MATERIALS[name]
    t = np.arange(0.0, 300.0 + dt / 2, dt)
    r = elongation_response(m, t, V * t)
    np.testing.assert_allclose(r.force[1:], _tensile_reference(m, t[1:]), rtol=1e-9)
    # plastic flow: p = x - recoverable, recoverable = F/k2 + x1 with x1 from Eq. 3 (k2 = inf)
    if not isinstance(m, Burgers):
        np.testing.assert_allclose(r.plastic[1:], V * t[1:] -
                                   cf.kv_elongation(m, t[1:], V), rtol=1e-9)


@pytest.mark.parametrize("dt", (0.3, 7.0, 40.0))
def test_imposed_elongation_on_irregular_samples(dt):
    rng = np.random.default_rng(3)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.2 * dt, 2 * dt, 30))])
    for m in MATERIALS.values():
        r = elongation_response(m, t, V * t)
        np.testing.assert_allclose(r.force[1:], _tensile_reference(m, t[1:]), rtol=1e-9)


@pytest.mark.parametrize("dt", STEPS)
@pytest.mark.parametrize("name", list(MATERIALS))
def test_stepped_force_creep_recovery_matches_closed_form(name, dt):
    m = MATERIALS[name]
    F, t1 = 0.5, 60.0
    t = np.unique(np.concatenate([np.arange(0.0, 400.0, dt), [t1, 400.0]]))
    r = force_response(m, t, np.where(t < t1, F, 0.0), hold="step")
    np.testing.assert_allclose(r.elongation, _creep_reference(m, t, F, t1), rtol=1e-9, atol=1e-15)
    # Eq. 9-10: what remains is F t1/c2 (the plastic part exactly, the total after recovery)
    assert r.plastic[-1] == pytest.approx(F * t1 / m.c2, rel=1e-12)
    assert r.elongation[-1] == pytest.approx(F * t1 / m.c2, rel=1e-9)


@pytest.mark.parametrize("dt", STEPS)
@pytest.mark.parametrize("name", list(MATERIALS))
def test_force_ramp_first_order_hold_matches_closed_form(name, dt):
    m = MATERIALS[name]
    a = 0.01                                 # N/s
    t = np.arange(0.0, 200.0 + dt / 2, dt)
    r = force_response(m, t, a * t, hold="linear")
    # x = a t j2 + a t^2/(2 c2) + (a/k1)(t - (c1/k1)(1 - exp(-k1 t/c1)))   (c1 = 0: a t/k1)
    kv = a * t / m.k1 if m.c1 == 0 else a / m.k1 * \
        (t - m.c1 / m.k1 * (1 - np.exp(-m.k1 * t / m.c1)))
    ref = a * t * _j2(m) + a * t ** 2 / (2 * m.c2) + kv
    np.testing.assert_allclose(r.elongation, ref, rtol=1e-9, atol=1e-15)


def test_creep_under_constant_force_is_eq7_8():
    t = np.linspace(0, 120, 13)
    for m in (PAPER, THREE):
        r = force_response(m, t, np.full_like(t, 0.5), hold="step")
        ref = 0.5 * t / m.c2 + (0.5 / m.k1 * (1 - np.exp(-m.k1 * t / m.c1))
                                if m.c1 else 0.5 / m.k1)
        np.testing.assert_allclose(r.elongation, ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(cf.creep_elongation(m, t, 0.5), ref, rtol=1e-12, atol=1e-15)


@settings(max_examples=40, deadline=None)
@given(k1=st.floats(1.0, 1e4), c1=st.floats(0.0, 1e4), c2=st.floats(10.0, 1e5),
       dt=st.floats(1e-3, 200.0), n=st.integers(1, 12))
def test_exact_step_for_any_constants_and_step(k1, c1, c2, dt, n):
    m = ThreeElement(k1, c1, c2)
    t = np.arange(n + 1) * dt
    r = elongation_response(m, t, V * t)
    np.testing.assert_allclose(r.force[1:], cf.tensile_force(m, t[1:], V), rtol=1e-9)


# ----------------------------------------------------------- the step itself
def test_elongation_step_kv_state_is_eq3_and_affine_law_holds():
    dt, delta = 2.0, 2.0 * V
    e1, p = 0.0, 0.0
    for i in range(1, 20):
        F0, S = step_coefficients(THREE.k1, THREE.c1, THREE.c2, e1, dt)
        F, e1, p = elongation_step(THREE.k1, THREE.c1, THREE.c2, e1, p, delta, dt)
        assert float(F) == pytest.approx(float(F0 + S * delta), rel=1e-13)
        assert float(e1) == pytest.approx(float(cf.kv_elongation(THREE, i * dt, V)), rel=1e-12)


def test_shortening_unit_goes_slack_and_keeps_its_plastic_elongation():
    F, e1, p = elongation_step(95.0, 0.0, 1300.0, 5e-3, 2e-3, 0.0, 1.0)
    assert float(F) > 0
    F, e1, p = elongation_step(95.0, 0.0, 1300.0, 5e-3, 2e-3, -6e-3, 1.0)
    assert float(F) == 0.0 and float(e1) == 0.0 and float(p) == 2e-3
    Fb, e1b, pb = burgers_elongation_step(BURG, 0.2, 1e-3, 2e-3, -0.01, 1.0)
    assert Fb == 0.0 and pb == 2e-3 and e1b == pytest.approx(1e-3 * math.exp(-95 / 300))


def test_vectorised_step_over_units():
    k1 = np.array([95.0, 190.0, 50.0])
    F, e1, p = elongation_step(k1, np.zeros(3), np.full(
        3, 1300.0), np.zeros(3), np.zeros(3), np.full(3, V), 1.0)
    for i in range(3):
        ref = cf.tensile_force(ThreeElement(k1[i], 0.0, 1300.0), 1.0, V)
        assert F[i] == pytest.approx(float(ref), rel=1e-12)


# ------------------------------------------------------------------ scaling
@pytest.mark.parametrize("m", [PAPER, THREE, BURG], ids=["maxwell", "three", "burgers"])
def test_scaling_two_half_units_in_series_are_one_unit(m):
    half = m.scaled(m.length / 2)
    assert half.k1 == pytest.approx(2 * m.k1) and half.c2 == pytest.approx(2 * m.c2)
    # each half of a unit pulled at v is pulled at v/2 and carries the same force
    t = np.linspace(0.5, 100, 20)
    ref = _tensile_reference(m, t)
    got = burgers_tensile_force(half, t, V / 2) if isinstance(m,
                                                              Burgers) else cf.tensile_force(half,
                                                                                             t,
                                                                                             V / 2)
    np.testing.assert_allclose(got, ref, rtol=1e-12)


# --------------------------------------------------------------- validation
@pytest.mark.parametrize("kwargs,name", [
    (dict(k1=float("nan"), c1=0, c2=1300), "k1"),
    (dict(k1=0.0, c1=0, c2=1300), "k1"),
    (dict(k1=-95, c1=0, c2=1300), "k1"),
    (dict(k1=95, c1=-1, c2=1300), "c1"),
    (dict(k1=95, c1=float("nan"), c2=1300), "c1"),
    (dict(k1=95, c1=0, c2=0.0), "c2"),
    (dict(k1=95, c1=0, c2=float("nan")), "c2"),
    (dict(k1=95, c1=0, c2=1300, length=0.0), "length"),
    (dict(k1=95, c1=0, c2=1300, length=-0.1), "length"),
])
def test_three_element_refuses_bad_constants(kwargs, name):
    with pytest.raises(ValueError) as exc:
        ThreeElement(**kwargs)
    msg = str(exc.value)
    assert msg.startswith(name) and "expected" in msg


@pytest.mark.parametrize("kwargs,name", [
    (dict(k1=95, c1=300, c2=1300, k2=0.0), "k2"),
    (dict(k1=95, c1=300, c2=float("inf"), k2=150), "c2"),
    (dict(k1=95, c1=300, c2=1300, k2=float("nan")), "k2"),
])
def test_burgers_refuses_bad_constants(kwargs, name):
    with pytest.raises(ValueError, match=f"^{name}.*expected"):
        Burgers(**kwargs)


@pytest.mark.parametrize("dt", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_time_steps_are_refused(dt):
    with pytest.raises(ValueError, match=r"dt \[s\] = .*expected a positive"):
        elongation_step(95.0, 0.0, 1300.0, 0.0, 0.0, 1e-3, dt)


def test_bad_histories_are_refused():
    with pytest.raises(ValueError, match=r"time t \[s\] = 1.0 at sample 2: .*\(strictly "
                                         r"increasing\)"):
        elongation_response(PAPER, [0.0, 1.0, 1.0], [0, 1e-3, 2e-3])
    with pytest.raises(ValueError, match=r"elongation \[m\] = nan at sample 1"):
        elongation_response(PAPER, [0.0, 1.0], [0.0, float("nan")])
    with pytest.raises(ValueError, match=r"force \[N\] = -0.1 at sample 1: expected >= 0"):
        force_response(PAPER, [0.0, 1.0], [0.0, -0.1])
    with pytest.raises(ValueError, match="hold"):
        force_response(PAPER, [0.0, 1.0], [0.0, 0.1], hold="cubic")
    with pytest.raises(ValueError, match=r"scaled|length \[m\] = 0"):
        PAPER.scaled(0.0)
    with pytest.raises(ValueError, match=r"speed \[m/s\] = -0.001"):
        cf.tensile_force(PAPER, 1.0, -1e-3)
    with pytest.raises(ValueError, match=r"time t \[s\] = -1.0"):
        cf.tensile_force(PAPER, -1.0, V)
