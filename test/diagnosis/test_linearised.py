"""The diagnosis's linearised fits against closed forms (no simulation, no ROS): a model whose
residual is exactly linear in the knobs and the effects' values, so the bounded least squares
away from its bounds is the ordinary least-squares solution and its interval the classical
one; and the cause ranking on signatures whose leading kind follows from its rules."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rheo_shaping.diagnosis.candidates import (GRID, PROBES, Explanation, LinearFit, fit_pair,
                                               fit_single, lr_interval)
from rheo_shaping.diagnosis.check import chord
from rheo_shaping.diagnosis.context import Group
from rheo_shaping.diagnosis.linear import Solver, Stack
from rheo_shaping.diagnosis.signature import CAUSES, SUBSTITUTE_SHARE, rank_causes

N = 400          # residual entries (one frame of profile points, no force)
K = 3            # sheet knobs


def _world(seed: int = 0):
    """Baseline columns A (N x K), three effect responses per unit value and a noise draw."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(N, K)) / math.sqrt(N)
    g = rng.normal(size=(N, 3)) / math.sqrt(N) * np.array([300.0, 300.0, 2.0])
    noise = rng.normal(size=N) * 1e-3
    return A, g, noise


def _lin(A: np.ndarray, z: np.ndarray, bound: float = 10.0) -> LinearFit:
    stack = Stack([np.zeros(N, int)], [False], 1.0, 1.0)
    lo, hi = -bound * np.ones(K), bound * np.ones(K)
    return LinearFit(z, Solver(A), lo, hi, stack, {"profile": float(N)}, stack.J_parts(z))


def _probes(name: str, g: np.ndarray) -> list:
    """Probe responses of effect ``name`` whose response is ``g`` per unit value (columns)."""
    kind, vals, _ = PROBES[name]
    out = []
    for v in vals:
        vv = v if isinstance(v, tuple) else (v,)
        out.append((vv, g @ np.asarray(vv, float) if g.ndim == 2 else g * vv[0]))
    return out


def test_fit_single_of_a_linear_effect_is_least_squares_with_the_classical_interval():
    """mass_error (one column): value and knobs are the least-squares solution of
    z + A u + g x = r; the 95 % half-width is sqrt(3.84 s^2 [(M^T M)^-1]_xx), s^2 = J / n."""
    A, g, noise = _world(1)
    u_true, x_true = np.array([0.3, -0.2, 0.5]), 0.12
    z = -(A @ u_true + g[:, 2] * x_true) + noise
    c = fit_single("mass_error", _probes("mass_error", g[:, 2]), _lin(A, z))
    M = np.column_stack((A, g[:, 2]))
    sol = np.linalg.lstsq(M, -z, rcond=None)[0]
    J = float(np.sum((z + M @ sol) ** 2))
    assert c.values["mass_error"][0] == pytest.approx(sol[K], rel=1e-9)
    np.testing.assert_allclose(c.baseline_u, sol[:K], rtol=1e-9)
    assert c.J == pytest.approx(J, rel=1e-9)
    half = math.sqrt(3.84 * J / N * np.linalg.inv(M.T @ M)[K, K])
    lo, hi = c.interval["mass_error"][0]
    assert (lo, hi) == pytest.approx((sol[K] - half, sol[K] + half), rel=1e-9)
    assert lo < x_true < hi                     # this draw's interval covers the truth
    assert c.LR == pytest.approx(N * math.log(float(z @ z) / J), rel=1e-9)


def test_fit_single_of_a_curve_effect_takes_the_grid_point_nearest_the_least_squares():
    """bending, its response linear in EI: J(a) is a parabola in the magnitude, so the grid's
    best point is the one nearest the least-squares magnitude, and the knobs there are the
    least squares with that magnitude held."""
    A, g, noise = _world(2)
    gb = g[:, 0] * 3.0                              # |gb| ~ 1e3 per N m^2: sd(a) ~ 1e-6
    a_true = 7.3e-6
    z = -(A @ np.array([0.1, 0.4, -0.3]) + gb * a_true) + noise
    c = fit_single("bending", _probes("bending", gb), _lin(A, z))
    a_ls = np.linalg.lstsq(np.column_stack((A, gb)), -z, rcond=None)[0][K]
    grid = np.linspace(0.0, PROBES["bending"][2], GRID)
    a_grid = grid[np.argmin(np.abs(grid - a_ls))]
    assert c.values["bending"][0] == a_grid
    u = np.linalg.lstsq(A, -(z + gb * a_grid), rcond=None)[0]
    np.testing.assert_allclose(c.baseline_u, u, rtol=1e-9)
    lo, hi = c.interval["bending"][0]
    assert lo < a_true < hi


def test_the_lr_interval_of_a_parabolic_misfit_is_the_closed_form():
    """J(a) = J_min + h (a - a0)^2: the magnitudes whose drop n ln(J / J(a_i)) stays within
    3.84 end at a0 +- sqrt((J(a_i) e^(3.84/n) - J_min) / h); linear interpolation of the drop
    between grid points errs by at most step^2 max|drop''| / (8 |drop'|)."""
    J_min, h, a0, n = 0.8, 2.0e4, 0.0123, 500.0
    grid = np.linspace(0.0, 0.03, 301)
    Js = J_min + h * (grid - a0) ** 2
    i = int(np.argmin(Js))
    lo, hi = lr_interval(grid, Js, i, n)
    half = math.sqrt((Js[i] * math.exp(3.84 / n) - J_min) / h)
    step = grid[1] - grid[0]
    for end in (a0 - half, a0 + half):
        J = J_min + h * (end - a0) ** 2
        slope = n * 2 * h * abs(end - a0) / J
        curv = n * 2 * h / J_min                 # bounds |drop''| <= n J'' / J
        tol = step ** 2 * curv / (8 * slope)
        got = lo if end < a0 else hi
        assert abs(got - end) <= tol, (got, end, tol)
    assert hi - lo > 10 * step                   # the interpolation, not the parabola floor


def test_the_lr_interval_never_narrower_than_the_parabola_on_a_coarse_grid():
    """Where the interval lies within one grid step, the parabola through the minimum and its
    neighbours gives it: half-width sqrt(2 * 3.84 / drop'') around the grid's minimum."""
    J_min, h, a0, n = 1.0, 1.0e6, 0.5, 400.0
    grid = np.linspace(0.0, 1.0, 11)
    Js = J_min + h * (grid - a0) ** 2
    lo, hi = lr_interval(grid, Js, 5, n)
    drop = n * np.log(Js / Js[5])
    curv = (drop[4] - 2 * drop[5] + drop[6]) / 0.1 ** 2
    half = math.sqrt(2 * 3.84 / curv)
    assert (lo, hi) == pytest.approx((0.5 - half, 0.5 + half), rel=1e-12)


def test_fit_pair_of_two_linear_effects_is_their_joint_least_squares():
    A, g, noise = _world(3)
    gt = g[:, :2]                                 # tool_offset (x, z), per metre
    x_true = np.array([1.5e-3, -0.8e-3, 0.2])
    z = -(A @ np.array([-0.2, 0.3, 0.1]) + gt @ x_true[:2] + g[:, 2] * x_true[2]) + noise
    responses = {"tool_offset": _probes("tool_offset", gt),
                 "mass_error": _probes("mass_error", g[:, 2])}
    lin = _lin(A, z)
    a = fit_single("tool_offset", responses["tool_offset"], lin)
    b = fit_single("mass_error", responses["mass_error"], lin)
    c = fit_pair(a, b, responses, lin)
    M = np.column_stack((A, gt, g[:, 2]))
    sol = np.linalg.lstsq(M, -z, rcond=None)[0]
    assert c.names == ("mass_error", "tool_offset") and c.k == 3
    assert c.values["tool_offset"] == pytest.approx(tuple(sol[K:K + 2]), rel=1e-9)
    assert c.values["mass_error"] == pytest.approx((sol[K + 2],), rel=1e-9)
    np.testing.assert_allclose(c.baseline_u, sol[:K], rtol=1e-9)
    assert c.J == pytest.approx(float(np.sum((z + M @ sol) ** 2)), rel=1e-9)
    # the pair explains what neither part does alone
    assert c.J < min(a.J, b.J)


def test_a_curve_effect_with_one_probe_that_ran_pairs_as_the_line_through_it():
    """kelvin_c1's second probe failed (its model did not run): the single and the pair fits
    both take the response as the line through the probe that ran (the gap watch's crash in
    ``response_at``, issue 29), and the pair finds the magnitude a response of that form
    was built with, on the pair's grid of 17 magnitudes to 3000 N s/m."""
    A, g, noise = _world(5)
    per_unit = g[:, 0] / 500.0                      # the response per N s/m, linear
    x_true = 1125.0                                 # on the pair's grid (3000 / 16 * 6)
    z = -(A @ np.array([0.1, -0.2, 0.3]) + per_unit * x_true + g[:, 2] * 0.1) + noise
    responses = {"kelvin_c1": [((500.0,), per_unit * 500.0), ((2000.0,), None)],
                 "mass_error": _probes("mass_error", g[:, 2])}
    lin = _lin(A, z)
    a = fit_single("kelvin_c1", responses["kelvin_c1"], lin)
    b = fit_single("mass_error", responses["mass_error"], lin)
    c = fit_pair(a, b, responses, lin)
    assert c.names == ("kelvin_c1", "mass_error")
    assert c.values["kelvin_c1"] == (pytest.approx(x_true),)
    assert c.values["mass_error"][0] == pytest.approx(0.1, abs=0.02)


def test_one_chord_step_of_an_exactly_linear_model_lands_on_its_least_squares():
    """From any point (u0, v0) of a model whose residual is r + A u + E v, one chord step goes
    to argmin |r + A u + E v|, the knobs and values inside their boxes."""
    A, g, noise = _world(4)
    gt = g[:, :2]
    r = -(A @ np.array([0.4, -0.6, 0.2]) + gt @ np.array([1.0e-3, 2.0e-3])) + noise
    u0, v0 = np.array([-0.5, 0.5, 0.0]), np.array([0.0, 0.0])
    c = Explanation(("tool_offset",), {"tool_offset": tuple(v0)}, 1.0,
                    baseline_u=u0.copy())
    c.search.z_raw = r + A @ u0 + gt @ v0
    G = Group([], Stack([np.zeros(N, int)], [False], 1.0, 1.0), np.zeros((N, 0)))
    u1, vals = chord(c, A, G, {"tool_offset": _probes("tool_offset", gt)})
    sol = np.linalg.lstsq(np.column_stack((A, gt)), -r, rcond=None)[0]
    np.testing.assert_allclose(u1, sol[:K], rtol=1e-9)
    assert vals["tool_offset"] == pytest.approx(tuple(sol[K:]), rel=1e-9)
    # half the step when the last one missed (damp 0.5)
    c.search.damp = 0.5
    u_half, vals_half = chord(c, A, G, {"tool_offset": _probes("tool_offset", gt)})
    np.testing.assert_allclose(u_half, u0 + 0.5 * (sol[:K] - u0), rtol=1e-9)


def _signature(**kw) -> dict:
    sig = {"observables": {"profile": 1.0, "tool force": 0.0},
           "proportional_to": {"tension": 0.0, "speed": 0.0, "strain": 0.0, "position": 0.0},
           "when": {"approach": 0.0, "forced deformation": 0.0, "dwell": 0.0, "release": 0.0,
                    "settle": 0.0},
           "before_contact": 0.0, "where": {"peak_band": 2}, "trend": {"kind": "constant"},
           "force_x_share": 0.0, "force_explained_by_gain_and_lag": 0.0,
           "profile_offset_share": 0.0, "partial_substitutes": {}}
    sig.update(kw)
    return sig


def _kinds(sig: dict) -> list[str]:
    ranked = rank_causes(sig)
    assert sorted(r["kind"] for r in ranked) == sorted(CAUSES)
    scores = [r["score"] for r in ranked if r["substitute_share"] is None
              or r["substitute_share"] < SUBSTITUTE_SHARE]
    assert scores == sorted(scores, reverse=True)
    return [r["kind"] for r in ranked]


def test_cause_ranking_follows_its_rules():
    """A profile-only gap all before contact, constant: a load (mass, gravity) before a
    bending stiffness (its gap peaks off the cake-top band); a force gap in x after the
    forming: contact friction; a library effect that imitates >= SUBSTITUTE_SHARE of the gap
    puts its kind first, a smaller share does not."""
    before = _signature(when={"approach": 1.0, "forced deformation": 0.0, "dwell": 0.0,
                              "release": 0.0, "settle": 0.0}, before_contact=1.0)
    assert _kinds(before)[:2] == ["mass or gravity load", "bending stiffness"]
    tie = _kinds(dict(before, where={"peak_band": 0}))       # peak at the cake top: 1.0 each
    assert set(tie[:2]) == {"bending stiffness", "mass or gravity load"}
    late = _signature(observables={"profile": 0.0, "tool force": 1.0},
                      when={"approach": 0.0, "forced deformation": 0.0, "dwell": 0.5,
                            "release": 0.3, "settle": 0.2}, force_x_share=1.0)
    assert _kinds(late)[0] == "contact friction"
    growing = _signature(trend={"kind": "growing"}, when=late["when"],
                         proportional_to={"tension": 0.0, "speed": 0.0, "strain": 0.9,
                                          "position": 0.0})
    assert _kinds(growing)[0] == "strain-dependent material"
    sub = dict(late, partial_substitutes={"tool position calibration": SUBSTITUTE_SHARE})
    assert _kinds(sub)[0] == "tool position calibration"
    weak = dict(late, partial_substitutes={"tool position calibration": 0.5 * SUBSTITUTE_SHARE})
    assert _kinds(weak)[0] == "contact friction"


def test_a_tool_offset_is_probed_on_both_sides_and_fitted_on_the_side_it_lies():
    """The tool offset's response is not odd: pressing deeper meets the contact, held higher it
    leaves it (here each axis responds three times as strongly below zero as above).  Probed on
    both sides, the fit takes each axis's column on the side its value lies and recovers a
    deep offset (+1.2 mm in x, -1.8 mm in z) to the noise; from the positive probes alone
    (the column continued through zero, the search before) it cannot."""
    assert set(PROBES["tool_offset"][1]) == {(1e-3, 0.0), (0.0, 1e-3), (-1e-3, 0.0),
                                             (0.0, -1e-3)}
    A, g, noise = _world(3)
    up, down = g[:, :2], 3.0 * g[:, :2] + g[:, 2:3]   # per metre, above and below zero

    def resp(v):
        v = np.asarray(v, float)
        return up @ np.maximum(v, 0.0) + down @ np.minimum(v, 0.0)
    truth = (1.2e-3, -1.8e-3)
    z = -(A @ np.array([0.2, -0.1, 0.3]) + resp(truth)) + noise
    both = [(v, resp(v)) for v in PROBES["tool_offset"][1]]
    c = fit_single("tool_offset", both, _lin(A, z))
    np.testing.assert_allclose(c.values["tool_offset"], truth, atol=2e-5)
    assert c.J == pytest.approx(float(noise @ noise), rel=0.05)
    for (lo, hi), t in zip(c.interval["tool_offset"], truth):
        assert lo < t < hi
    one = fit_single("tool_offset", both[:2], _lin(A, z))
    assert one.J > 10 * c.J
    assert abs(one.values["tool_offset"][1] - truth[1]) > 3e-4
    # the chord's columns are the side each value lies on
    from rheo_shaping.diagnosis.check import effect_columns
    cols = dict(effect_columns("tool_offset", {"tool_offset": both}, (1e-3, -1e-3)))
    np.testing.assert_allclose(cols[0], up[:, 0])
    np.testing.assert_allclose(cols[1], down[:, 1])
    # a pair with a curve effect takes the sides too
    gb = g[:, 0] * 3.0
    zp = z - gb * 4e-6
    pc = fit_pair(c, Explanation(("bending",), {"bending": (4e-6,)}, 0.0),
                  {"tool_offset": both, "bending": _probes("bending", gb)}, _lin(A, zp))
    np.testing.assert_allclose(pc.values["tool_offset"], truth, atol=1e-4)
