"""Identification: the paper's three steps, the joint fit, model choice, data files.

Acceptance figures (asserted here, reported in docs/material.md):
(a) Table 1 -> c2 within 1 % of 1.30e3 N s/m, with its standard error;
(b) synthetic tensile curves (1 % noise, load-cell offset, break at ~1.04 N
    and a force drop) of known materials -> Maxwell k1, c2 within 2 % and
    c1 ~ 0; three-element c1 within 10 %; Burgers told from three-element.
"""
from __future__ import annotations

import math
from importlib import resources

import numpy as np
import pytest

from rheo_shaping.material.burgers import Burgers
from rheo_shaping.material.closed_forms import tensile_force
from rheo_shaping.identification.crack import detect_crack
from rheo_shaping.identification.paper_method import (
    c1_from_tensile,
    c2_from_creep,
    identify_paper,
    k1_by_linear_least_squares,
    prepare_tensile,
)
from rheo_shaping.identification.joint_fit import FitData, fit_model
from rheo_shaping.material.three_element import ThreeElement, maxwell
from rheo_shaping.identification.material_data import (
    DataFormatError,
    TensileCurve,
    read_creep_residuals,
    read_material_file,
    read_tensile_curve,
)
from rheo_shaping.identification.model_choice import identify_joint
from rheo_shaping.identification.synthetic_material import (
    synthetic_creep_curve,
    synthetic_creep_residuals,
    synthetic_tensile_curve,
    synthetic_tensile_set,
)

TABLE1_MM = [22.9, 24.6, 23.0, 22.0, 24.0, 22.8, 23.7, 21.7, 22.9, 23.4]
MAXWELL = maxwell(95.0, 1300.0)
THREE = ThreeElement(95.0, 300.0, 1300.0)
BURG = Burgers(95.0, 300.0, 1300.0, 150.0)


def table1_path():
    return resources.files("rheo_shaping") / "data" / "table1_creep.csv"


# --------------------------------------------------------------- (a) Table 1
def test_table1_file_holds_the_paper_numbers():
    d = read_creep_residuals(table1_path())
    np.testing.assert_allclose(d.residual, np.array(TABLE1_MM) * 1e-3, rtol=1e-12)
    assert set(d.force) == {0.5} and set(d.t1) == {60.0} and d.length == 0.1
    assert d.residual.mean() == pytest.approx(23.1e-3, abs=1e-6)
    assert d.residual.std(ddof=0) == pytest.approx(
        0.83e-3, abs=5e-6)      # the paper's sd is ddof = 0
    text = table1_path().read_text()
    assert "Table 1" in text and "F = 0.5 N" in text and "t1 = 60 s" in text


def test_acceptance_a_c2_from_table1():
    c2 = c2_from_creep(read_creep_residuals(table1_path()))
    x = np.array(TABLE1_MM) * 1e-3
    expected = 0.5 * 60.0 / x.mean()                                     # Eq. 10
    expected_se = expected * x.std(ddof=1) / math.sqrt(x.size) / x.mean()
    assert c2.value == pytest.approx(expected, rel=1e-12)
    assert abs(c2.value / 1.30e3 - 1) < 0.01
    assert c2.se == pytest.approx(expected_se, rel=1e-9)
    assert c2.ci95[0] < 1.30e3 < c2.ci95[1]
    # the joint fit on the same table gives the same c2 and the same error
    j = identify_joint(residuals=[read_creep_residuals(table1_path())])
    assert j.params["c2"].value == pytest.approx(expected, rel=1e-8)
    assert j.params["c2"].se == pytest.approx(expected_se, rel=1e-5)
    assert j.params["k1"].value is None and j.model is None


# ---------------------------------------------------------- crack detection
def test_crack_is_found_before_the_drop_and_nothing_after_is_kept():
    for seed in range(4):
        s = synthetic_tensile_curve(MAXWELL, 1e-3, seed=seed, break_spread=0.03)
        d = detect_crack(s.curve.t, s.curve.force)
        assert d.found
        assert s.curve.t[d.keep - 1] <= s.t_break                      # no point after the break
        assert s.t_break - d.t_crack < 1.5                            # and not much lost before it


def test_no_crack_when_the_pull_stays_below_the_break_force():
    # c2 v = 0.65 N < 1.04 N: the curve reaches its plateau (Eq. 6) without breaking
    s = synthetic_tensile_curve(MAXWELL, 0.5e-3, seed=1, t_max=90.0)
    assert s.t_break is None
    d = detect_crack(s.curve.t, s.curve.force)
    assert not d.found and d.keep == s.curve.t.size


# ------------------------------------------------------ paper steps, exact
def _exact_curve(m, v=1e-3, t_end=20.0):
    t = np.arange(-2.0, t_end + 1e-9, 0.1)
    F = np.where(t > 0, tensile_force(m, np.maximum(t, 0), v), 0.0)
    return TensileCurve(t, F, v)


@pytest.mark.parametrize("m", [MAXWELL, THREE], ids=["maxwell", "three-element"])
def test_paper_steps_recover_exact_constants(m):
    from rheo_shaping.identification.estimates import Estimate
    curves = [prepare_tensile(_exact_curve(m))]
    c2 = Estimate(m.c2, 0.0, None, "N s/m")
    c1, _ = c1_from_tensile(curves, c2)
    assert c1.value == pytest.approx(m.c1, abs=1e-4 * m.c2)   # Eq. 11 (extrapolated F(0))
    k1, b = k1_by_linear_least_squares(curves, Estimate(m.c1, 0.0, None, "N s/m"), c2)
    assert b.value == pytest.approx(m.k1 / (m.c1 + m.c2), rel=1e-6)   # Eq. 12-13
    assert k1.value == pytest.approx(m.k1, rel=1e-6)


# ------------------------------------------------------- (b) acceptance
@pytest.fixture(scope="module")
def campaigns():
    """Five synthetic curves at 1e-3 m/s per material (offsets drawn, sd 0.02 N)."""
    return {name: [s.curve for s in synthetic_tensile_set(m, (1e-3,), 5, seed=11,
                                                          break_spread=0.02)]
            for name, m in (("maxwell", MAXWELL), ("three", THREE), ("burgers", BURG))}


@pytest.fixture(scope="module")
def joint(campaigns):
    return {name: identify_joint(curves) for name, curves in campaigns.items()}


def test_synthetic_curves_have_offsets_breaks_and_drops(campaigns):
    for c in campaigns["maxwell"]:
        rest = c.force[c.t <= 0]
        assert abs(rest.mean()) > 1e-4                                  # an offset
        i = int(np.argmax(c.force))
        assert 0.95 < c.force[i] - rest.mean() < 1.15                   # break near 1.04 N
        assert c.force[-1] - rest.mean() < 0.05                         # then the force is gone


def test_acceptance_b_maxwell_k1_c2_within_2_percent_and_c1_zero(joint):
    r = joint["maxwell"]
    assert r.model == "maxwell"
    assert abs(r.params["k1"].value / 95.0 - 1) < 0.02
    assert abs(r.params["c2"].value / 1300.0 - 1) < 0.02
    c1 = r.params["c1"]
    assert c1.value == 0.0 and c1.ci95[0] == 0.0 and c1.ci95[1] < 0.01 * 1300.0
    for n in ("k1", "c2"):
        lo, hi = r.params[n].ci95
        assert lo < {"k1": 95.0, "c2": 1300.0}[n] < hi


def test_acceptance_b_three_element_c1_within_10_percent(joint):
    r = joint["three"]
    assert r.model == "three-element"
    assert abs(r.params["c1"].value / 300.0 - 1) < 0.10
    assert abs(r.params["k1"].value / 95.0 - 1) < 0.02
    assert abs(r.params["c2"].value / 1300.0 - 1) < 0.02


def test_acceptance_b_burgers_told_from_three_element(joint):
    rb, r3 = joint["burgers"], joint["three"]
    assert rb.best_aic == rb.best_bic == "burgers"
    assert rb.fits["three-element"].bic - rb.fits["burgers"].bic > 10.0
    # and not Burgers on three-element data
    assert r3.best_bic == "three-element"
    assert abs(rb.params["k2"].value / 150.0 - 1) < 0.05


def test_paper_method_on_the_synthetic_campaigns(campaigns):
    creep = synthetic_creep_residuals(MAXWELL, seed=5)
    r = identify_paper(creep, campaigns["maxwell"])
    assert r.model == "maxwell" and r.c1.value == 0.0
    assert abs(r.k1.value / 95.0 - 1) < 0.02 and abs(r.c2.value / 1300.0 - 1) < 0.02
    r3 = identify_paper(synthetic_creep_residuals(THREE, seed=5), campaigns["three"])
    assert r3.model == "three-element" and abs(r3.c1.value / 300.0 - 1) < 0.10


# ---------------------------------------------------- honesty of the errors
def test_joint_standard_errors_are_calibrated():
    """Over 24 seeds the z-scores (estimate - truth)/se have a sd near 1 (not over-confident)."""
    z = []
    for seed in range(24):
        curve = synthetic_tensile_curve(MAXWELL, 1e-3, seed=100 + seed).curve
        fit = fit_model("maxwell", FitData([prepare_tensile(curve)]))
        z.append([(fit.params[n].value - t) / fit.params[n].se for n,
                 t in (("k1", 95.0), ("c2", 1300.0))])
    z = np.array(z)
    assert np.all(np.abs(z.mean(axis=0)) < 0.8)
    assert np.all((0.5 < z.std(axis=0)) & (z.std(axis=0) < 1.6))


def test_without_rest_samples_or_creep_c1_is_confounded_with_the_offset():
    curves = [synthetic_tensile_curve(THREE, 1e-3, seed=3, t_rest=0.0).curve]
    r = identify_joint(curves, models=("maxwell", "three-element"))
    assert r.fits["three-element"].params["c1"].se is None
    assert any("confounded" in n for n in r.notes)
    # a creep table fixes c2 and with it c1 (from the shape of the curve)
    r2 = identify_joint(curves, [synthetic_creep_residuals(
        THREE, seed=3)], models=("maxwell", "three-element"))
    assert r2.model == "three-element"
    assert r2.fits["three-element"].params["c1"].se is not None
    assert abs(r2.params["c1"].value / 300 - 1) < 0.2


def test_creep_curves_alone_identify_every_constant():
    curves = [synthetic_creep_curve(THREE, seed=s, sd=2e-5) for s in range(3)]
    r = identify_joint(creep_curves=curves, models=("maxwell", "three-element"))
    assert r.model == "three-element"
    for n, truth in (("k1", 95.0), ("c1", 300.0), ("c2", 1300.0)):
        assert abs(r.params[n].value / truth - 1) < 0.05


def test_paper_method_needs_creep_data():
    with pytest.raises(ValueError, match="creep"):
        identify_paper(None, [])


# ------------------------------------------------------------ data files
def test_file_errors_name_file_line_and_column(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("# speed_m_per_s: 0.001\nt_s,F_N\n0,0\n0.1,abc\n")
    with pytest.raises(DataFormatError, match=r"bad.csv: line 4, column 2 \(F_N\): 'abc' is not a "
                                              r"number"):
        read_tensile_curve(p)
    p.write_text("t_s,F_N\n0,0\n0.1\n")
    with pytest.raises(DataFormatError, match=r"line 3, column 2: 1 fields, expected 2"):
        read_tensile_curve(p, 1e-3)
    p.write_text("t_s,F_N\n0,0\n0.2,1\n0.1,1\n")
    with pytest.raises(DataFormatError, match=r"line 4, column 1 \(t_s\).*increase"):
        read_tensile_curve(p, 1e-3)
    p.write_text("test,F_N,t1_s,x_residual_m\n1,0.5,60,-0.02\n")
    with pytest.raises(DataFormatError, match=r"line 2, column 4 \(x_residual_m\).*positive"):
        read_creep_residuals(p)
    p.write_text("a,b\n1,2\n")
    with pytest.raises(DataFormatError, match=r"line 1.*none of the known formats"):
        read_material_file(p)
    with pytest.raises(DataFormatError, match=r"missing.csv: no such file"):
        read_material_file(tmp_path / "missing.csv")
    p.write_text("# speed_m_per_s: 0.002\nt_s,F_N\n0,0\n0.1,1\n")
    with pytest.raises(DataFormatError, match=r"line 1: speed_m_per_s = 0.002 contradicts"):
        read_tensile_curve(p, 1e-3)


def test_packaged_synthetic_curve_is_labelled_and_readable():
    p = resources.files("rheo_shaping") / "data" / "synthetic_tensile_paper_params.csv"
    assert p.read_text().startswith("# SYNTHETIC DATA - NOT MEASURED")
    c = read_material_file(p)
    assert isinstance(c, TensileCurve) and c.speed == 1e-3
