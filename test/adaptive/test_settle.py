"""The closed loop's cheaper model runs (rheo_shaping.adaptive.settle, replan's early stop):
the settled sheet to first order within its radius agrees with the exact settle far below
the observables' noise, and a tension corner's run stopped past the limit changes no
prediction a re-plan acts on."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from rheo_shaping.adaptive.settle import material_cell
from rheo_shaping.adaptive.observe import NoiseModel
from rheo_shaping.adaptive.optimum import truth
from rheo_shaping.adaptive.replan import ReplanLimits, _Predictor
from rheo_shaping.adaptive.schedule import Choice, fixed_schedule
from rheo_shaping.adaptive.settle import LinearSettle
from rheo_shaping.params.cell import CellParams


def test_the_first_order_settle_is_exact_at_its_reference_and_close_within_its_radius():
    cell = CellParams()
    s = LinearSettle.about(cell)
    ref = np.array([0.1, -0.2, 0.05])
    s.recentre(ref)
    assert s.exact_settles == 4                   # the reference and one step per knob
    at = s.state(ref)
    exact_ref = s.exact(ref)
    for f in ("x", "v", "e1", "p", "tension", "contact"):
        assert np.array_equal(getattr(at, f), getattr(exact_ref, f)), f
    noise = NoiseModel()
    rng = np.random.default_rng(43)
    for _ in range(5):
        d = rng.uniform(-s.radius, s.radius, 3)
        approx, exact = s.state(ref + d), s.exact(ref + d)
        moved = np.max(np.abs(exact.x - exact_ref.x))
        err_x = np.max(np.abs(approx.x - exact.x))
        err_t = np.max(np.abs(approx.tension - exact.tension))
        # second order: a small part of what the settle moved, far below the noise
        assert err_x <= 0.15 * moved, (d, err_x, moved)
        assert err_x <= 0.05 * noise.gap, (d, err_x)
        assert err_t <= 0.1 * noise.tension, (d, err_t)


def test_beyond_its_radius_the_settle_is_exact_and_a_resting_point_moves_the_reference():
    s = LinearSettle.about(CellParams())
    s.recentre(np.zeros(3))
    far = np.array([0.2, 0.0, 0.0])
    before = s.exact_settles
    st = s.state(far)
    assert s.exact_settles == before + 1
    assert np.array_equal(st.x, s.exact(far).x)
    s.follow(far)                                 # first seen there: not yet a reference
    assert np.array_equal(s.theta_r, np.zeros(3))
    s.follow(far + 0.01)                          # came to rest: the reference moves
    assert np.allclose(s.theta_r, far + 0.01)


def test_a_tension_run_stopped_past_the_limit_changes_no_feasible_prediction():
    """Movement 1, a stiff heavy batch at the join (t = 20 s): each candidate's prediction
    with the early stop against its whole run.  Feasible ones are bit-equal; infeasible ones
    stay infeasible with a lower bound of the tension past the limit."""
    cell = replace(CellParams(), movement=replace(CellParams().movement, number=1))
    true = material_cell(cell, np.array([95.0, 1300.0, 0.3125]) * np.array([1.3, 1.2, 1.1]))
    sched = fixed_schedule(cell)
    limits = ReplanLimits(F_limit=0.85)
    pred = _Predictor(cell, truth(true), sched, 20.0, limits)
    stopped = 0
    for speed in limits.speeds:
        s = sched.rejoin(20.0, Choice(speed, 1.0))
        assert s is not None
        fast, whole = pred.future(s), pred.future(s, whole_run=True)
        assert whole.complete
        if whole.F_max <= limits.F_limit:
            assert fast == whole
        else:
            stopped += not fast.complete
            assert limits.F_limit < fast.F_max <= whole.F_max
            assert math.isinf(fast.delta) and not fast.feasible(limits)
    assert stopped >= 1                             # the early stop was exercised
