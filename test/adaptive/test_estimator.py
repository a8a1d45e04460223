"""The online estimate (rheo_shaping.adaptive.estimator): a known perturbation of k1, c2 and
the mass per length recovered from a synthetic run within the stated uncertainty; a lying
or diverging input turns the status bad, and it stays bad."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.adaptive.estimator import (EstimateStatus, Estimator, EstimatorParams,
                                             material_cell)
from rheo_shaping.adaptive.observe import NoiseModel, Sample, noisy
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import run_movement
from rheo_shaping.sheet.metrics import contact_tension, residual_gap

NOMINAL = np.array([95.0, 1300.0, 0.3125])
TRUTH = NOMINAL * np.array([1.25, 0.8, 1.1])          # k1 +25 %, c2 -20 %, mass +10 %


def _samples(cell: CellParams, seed: int = 7) -> list[Sample]:
    """What the cell of ``cell`` measures over the params file's movement, with noise."""
    run = run_movement(cell)
    rng = np.random.default_rng(seed)
    out = []
    for k in range(run.t.size):
        gap = residual_gap(run.nodes(k), cell.sheet.thickness)
        s = Sample(t=float(run.t[k]), tool=(float(run.tool[k, 0]), float(run.tool[k, 1])),
                   wrench=(float(run.tool_force[k, 0]), float(run.tool_force[k, 1])),
                   contact_tension=contact_tension(run.tension[k], run.tool_contact[k]),
                   gap=gap if math.isfinite(gap) else None)
        out.append(noisy(s, NoiseModel(), rng))
    return out


@pytest.fixture(scope="module")
def truth_samples() -> list[Sample]:
    return _samples(material_cell(CellParams(), TRUTH))


def test_before_any_sample_the_estimate_is_the_params_file_with_the_prior():
    est = Estimator(CellParams())
    e = est.estimate
    assert e.status is EstimateStatus.PRIOR and e.status.usable
    assert e.theta.tolist() == NOMINAL.tolist()
    assert e.sigma_rel.tolist() == pytest.approx([0.3, 0.3, 0.2], rel=1e-12)


def test_a_known_perturbation_is_recovered_within_the_stated_uncertainty(truth_samples):
    est = Estimator(CellParams(), EstimatorParams(max_iterations=3))
    for t_end in (20.0, 40.0, 60.0, 80.0, 120.0):      # refreshes as the run goes on
        e = est.update([s for s in truth_samples if t_end - 20.0 < s.t <= t_end])
        assert e.status is EstimateStatus.OK, e.message
    z = np.log(e.theta / TRUTH) / e.sigma_rel          # error in units of the stated sigma
    assert np.all(np.abs(z) <= 3.0), (e.theta, TRUTH, e.sigma_rel)
    assert np.all(e.sigma_rel < 0.03)                  # the data, not the prior, decide
    assert np.all(np.abs(np.log(e.theta / TRUTH)) < np.abs(np.log(NOMINAL / TRUTH)) / 5)
    # weighed by noise and model error in quadrature, the model's own data give chi^2 < 1
    assert 0.05 < e.chi2_dof < 1.0
    assert e.cost_s > 0.0 and e.n_samples > 100


@pytest.mark.parametrize("bad, words", [
    (dict(wrench=(math.nan, 0.0)), "wrench x = nan"),
    (dict(gap=math.inf), "gap = inf"),
    (dict(wrench=(0.0, 50.0)), "force 50 N"),                      # > 10 x F_break: a liar
    (dict(contact_tension=-20.0), "force 20 N"),
])
def test_a_lying_sample_sets_bad_input_and_it_latches(truth_samples, bad, words):
    est = Estimator(CellParams())
    good = [s for s in truth_samples if s.t <= 10.0]
    assert est.update(good[:-1]).status is EstimateStatus.OK
    e = est.update([replace(good[-1], **bad)])
    assert e.status is EstimateStatus.BAD_INPUT and not e.status.usable
    assert words in e.message
    later = est.update([s for s in truth_samples if 10.0 < s.t <= 20.0])
    assert later.status is EstimateStatus.BAD_INPUT and later.message == e.message


def test_a_sample_back_in_time_is_bad_input(truth_samples):
    est = Estimator(CellParams())
    e = est.update([truth_samples[5], truth_samples[4]])
    assert e.status is EstimateStatus.BAD_INPUT
    assert "expected after the previous sample's" in e.message


def test_a_force_the_model_cannot_explain_makes_the_fit_diverge(truth_samples):
    """A load cell reading three times the force (plausible numbers, a lying gain): no
    material explains it and the gap together; the estimator says so instead of planning
    on it."""
    est = Estimator(CellParams(), EstimatorParams(max_iterations=3))
    liar = [replace(s, wrench=(3 * s.wrench[0], 3 * s.wrench[1]),
                    contact_tension=None if s.contact_tension is None
                    else 3 * s.contact_tension) for s in truth_samples]
    statuses = [est.update([s for s in liar if t - 20.0 < s.t <= t]).status
                for t in (20.0, 40.0, 60.0, 80.0)]
    assert statuses[-1] is EstimateStatus.DIVERGED, est.estimate.message
    assert "diverged" in est.estimate.message


@pytest.mark.parametrize("name, value", [("prior_k1", 0.0), ("model_spacing", -1.0),
                                         ("max_chi2", math.nan), ("skip_before", math.inf)])
def test_bad_settings_are_refused_with_the_name(name, value):
    with pytest.raises(ValueError, match=name):
        EstimatorParams(**{name: value})
