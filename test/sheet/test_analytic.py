"""Reference solutions: exact lumped elastic chain and Irvine's elastic catenary."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from rheo_shaping.sheet.analytic import elastic_chain_equilibrium, solve_elastic_chain
from rheo_shaping.sheet.catenary import (discretise_cable, inextensible_catenary, irvine_catenary,
                                         solve_irvine)

G = 9.81
# The paper's fondant strip: k1 = 95 N/m on the 0.1 m specimen -> EA = 9.5 N; 0.3 kg/m.
EA = 95.0 * 0.1
W = 0.3 * G
CASES = {
    "asymmetric": dict(span=0.10, height_difference=-0.08, unstretched_length=0.15),
    "nearly_symmetric": dict(span=0.10, height_difference=-0.002, unstretched_length=0.15),
}


def node_force_residual(a, b, pos, rest, k, m, g=G) -> tuple[np.ndarray, np.ndarray]:
    """Net force [N] on every mass from k (l - L) links and gravity; link lengths [m]."""
    allp = np.vstack((a, pos, b))
    seg = np.diff(allp, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    f = (k * (length - rest) / length)[:, None] * seg           # pull of each link towards B
    net = f[1:] - f[:-1]
    net[:, 1] -= m * g
    return net, length


# ---------------------------------------------------------------- lumped chain


@pytest.mark.parametrize("seed", range(6))
def test_random_chain_is_in_exact_equilibrium(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.choice([1, 2, 7, 30]))
    rest = rng.uniform(0.004, 0.02, n + 1)
    k = rng.uniform(100.0, 5000.0, n + 1)
    m = rng.uniform(0.0, 0.01, n)
    a = rng.uniform(-0.1, 0.1, 2)
    ang = rng.uniform(0, 2 * math.pi)
    b = a + rng.uniform(0.3, 1.3) * rest.sum() * np.array([math.cos(ang), math.sin(ang)])
    sol = solve_elastic_chain(a, b, rest, k, m, G)
    net, length = node_force_residual(a, b, sol.positions, rest, k, m)
    assert np.abs(net).max() < 1e-12
    assert sol.mismatch <= 1e-12
    assert np.all(length > rest)                                  # every link taut
    assert np.allclose(sol.tensions, k * (length - rest), rtol=1e-10, atol=1e-13)
    assert np.array_equal(elastic_chain_equilibrium(a, b, rest, k, m, G), sol.positions)


def test_weightless_chain_is_straight():
    a, b = np.array([0.0, 0.1]), np.array([0.3, -0.1])
    rest = np.array([0.05, 0.1, 0.07, 0.08])
    k = np.array([100.0, 300.0, 50.0, 1000.0])
    sol = solve_elastic_chain(a, b, rest, k, np.zeros(3))
    chord = np.hypot(*(b - a))
    t = (chord - rest.sum()) / np.sum(1.0 / k)
    assert np.allclose(sol.tensions, t, rtol=1e-13)
    along = np.cumsum(rest + t / k)[:3] / chord
    assert np.allclose(sol.positions, a + along[:, None] * (b - a), atol=1e-15)


def test_chain_errors():
    a, b = (0.0, 0.0), (0.1, 0.0)
    with pytest.raises(ValueError, match="slack"):
        solve_elastic_chain(a, b, [0.06, 0.06], [100.0, 100.0], [0.0])
    with pytest.raises(ValueError, match="rest_lengths"):
        solve_elastic_chain(a, b, [0.06], [100.0, 100.0], [0.01])
    with pytest.raises(ValueError, match="stiffness"):
        solve_elastic_chain(a, b, [0.06, 0.06], [100.0, -1.0], [0.01])
    with pytest.raises(ValueError, match="masses"):
        solve_elastic_chain(a, b, [0.06, 0.06], [100.0, 100.0], [-0.01])
    with pytest.raises(ValueError, match="anchor_b"):
        solve_elastic_chain(a, (0.1, np.nan), [0.06, 0.06], [100.0, 100.0], [0.01])


# ----------------------------------------------------------- Irvine's catenary


@pytest.mark.parametrize("case",
                         [dict(span=0.1, height_difference=-0.08, unstretched_length=0.15, EA=EA),
                          dict(span=0.1, height_difference=-0.002,
                               unstretched_length=0.15, EA=EA),
                          dict(span=0.1, height_difference=0.05,
                               unstretched_length=0.5, EA=EA),
                          dict(span=0.1, height_difference=0.0,
                               unstretched_length=0.09, EA=EA),
                          dict(span=2.0, height_difference=0.7, unstretched_length=2.5,
                               EA=1e6)])
def test_irvine_boundary_conditions_and_constitutive_law(case):
    cab = solve_irvine(weight_per_length=W, **case)
    x, z = cab.position([0.0, cab.L0])
    assert x[0] == 0.0 and z[0] == 0.0
    assert abs(x[1] - cab.span) <= 1e-12 and abs(z[1] - cab.height_difference) <= 1e-12
    # d(x, z)/ds = (1 + T/EA) (H, w s - V) / T: stretch and direction of the closed form
    s = np.linspace(0.05, 0.95, 7) * cab.L0
    h = 1e-6 * cab.L0
    xp, zp = cab.position(s + h)
    xm, zm = cab.position(s - h)
    t = cab.tension(s)
    dx, dz = (xp - xm) / (2 * h), (zp - zm) / (2 * h)
    assert np.allclose(dx, (1 + t / cab.EA) * cab.H / t, atol=1e-8)
    assert np.allclose(dz, (1 + t / cab.EA) * (cab.w * s - cab.V) / t, atol=1e-8)
    # global vertical balance: the supports carry the weight
    assert cab.V + (cab.w * cab.L0 - cab.V) == pytest.approx(cab.w * cab.L0)


def test_irvine_stiff_limit_is_inextensible_catenary():
    l, h, big_l = 0.1, -0.08, 0.15
    # the reference itself: through both supports, with the right length
    zc = lambda x: inextensible_catenary(l, h, big_l, x)  # noqa: E731
    assert abs(zc(0.0)) < 1e-15 and abs(zc(l) - h) < 1e-14
    eps = 1e-7
    length = quad(lambda x: math.hypot(
        1.0, (zc(x + eps) - zc(x - eps)) / (2 * eps)), 0, l, epsabs=1e-13)[0]
    assert length == pytest.approx(big_l, abs=1e-8)
    s = np.linspace(0.0, big_l, 31)
    x, z = irvine_catenary(l, h, big_l, 1e9, W, s)
    assert np.abs(z - zc(x)).max() < 1e-9
    # and a soft cable sags measurably more than the stiff one
    x2, z2 = irvine_catenary(l, h, big_l, EA, W, s)
    assert np.abs(z2 - zc(x2)).max() > 1e-3


def test_irvine_taut_nearly_straight_matches_simple_statics():
    l, h, l0, ea, w = 0.1, -0.02, 0.09, EA, 1e-4        # almost weightless, stretched 13 %
    chord = math.hypot(l, h)
    t_bar = ea * (chord / l0 - 1.0)                      # bar statics
    cab = solve_irvine(l, h, l0, ea, w)
    assert cab.H == pytest.approx(t_bar * l / chord, rel=1e-9)
    # moment about B: V l + H h = W (l - x_bar), x_bar = l / 2 for a straight uniform cable
    weight = w * l0
    assert cab.V == pytest.approx(0.5 * weight - h * cab.H / l, abs=1e-5 * weight)
    s = np.linspace(0, l0, 11)
    x, z = cab.position(s)
    assert np.allclose(x, s / l0 * l, atol=1e-6) and np.allclose(z, s / l0 * h, atol=1e-6)
    # sag at mid-span ~ w L^2 / (8 T) (string statics), z below the chord
    _, zm = cab.position(0.5 * l0)
    sag = 0.5 * h - zm
    assert sag == pytest.approx(weight * l / (8 * cab.H), rel=0.05)


def test_irvine_errors():
    with pytest.raises(ValueError, match="span"):
        irvine_catenary(0.0, -0.08, 0.15, EA, W, [0.0])
    with pytest.raises(ValueError, match="EA"):
        irvine_catenary(0.1, -0.08, 0.15, -1.0, W, [0.0])
    with pytest.raises(ValueError, match="s \\[m\\]"):
        irvine_catenary(0.1, -0.08, 0.15, EA, W, [0.2])


# ------------------------------------------------- chain -> Irvine convergence


def test_discretise_cable_lumps_the_weight():
    c = discretise_cable(0.1, -0.08, 0.15, EA, W, 9)
    assert c.rest_lengths.shape == (10,) and np.allclose(c.rest_lengths, 0.015)
    assert np.allclose(c.stiffness, EA / 0.015)
    # interior masses + two half links at the supports = the whole cable
    assert c.masses.sum() * G + W * 0.015 == pytest.approx(W * 0.15)
    assert np.allclose(c.s_nodes, 0.015 * np.arange(1, 10))
    with pytest.raises(ValueError, match="n_masses"):
        discretise_cable(0.1, -0.08, 0.15, EA, W, 0)


@pytest.mark.parametrize("name", sorted(CASES))
def test_chain_converges_to_irvine_second_order(name):
    case = CASES[name]
    cab = solve_irvine(EA=EA, weight_per_length=W, **case)
    errors, h_err = [], []
    ns = [10, 20, 40, 80, 160]
    for n in ns:
        lumped = discretise_cable(EA=EA, weight_per_length=W, n_masses=n, **case)
        sol = lumped.solve()
        net, _ = node_force_residual(lumped.anchor_a, lumped.anchor_b, sol.positions,
                                     lumped.rest_lengths, lumped.stiffness, lumped.masses)
        assert np.abs(net).max() < 1e-12
        x, z = cab.position(lumped.s_nodes)
        errors.append(np.hypot(sol.positions[:, 0] - x, sol.positions[:, 1] - z).max())
        h_err.append(abs(sol.H - cab.H))
    errors = np.array(errors)
    scaled = errors * (np.array(ns) + 1.0) ** 2          # error ~ C / (N + 1)^2 = C h^2 / L0^2
    assert scaled.max() / scaled.min() < 1.25
    assert np.all(errors[:-1] / errors[1:] > 3.5)
    assert errors[-1] < 2e-6
    assert np.all(np.diff(h_err) < 0) and h_err[-1] < 1e-4 * cab.H
