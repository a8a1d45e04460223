"""The model's initial state from the records (issue 26, point 2): a laid sheet released at
the first frame, read from the frame alone, against the dynamic world that laid it."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.diagnosis import initial_state as ist
from rheo_shaping.diagnosis.compare import polylines_at
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.sheet.simulation import LaidSheet, run_scenario
from rheo_shaping_validation.worlds.dynamic import _polyline_length, laid_shape, run_world
from rheo_shaping_validation.worlds.params import LayParams
from rheo_shaping_validation.worlds.sensors import SensorParams, measure_world

LAY = LayParams(mode2=0.44, lift=5e-4, prestrain=0.0, let_go=0.25)


@pytest.fixture(scope="module")
def released():
    """A drawn laying released in the dynamic world, movement 4 (the tool stays away for the
    first 20 s), 6 s; the cell at N = 31 for the model."""
    p = CellParams()
    p = replace(p, sheet=replace(p.sheet, n_masses=31),
                movement=replace(p.movement, number=4, process_time=70.0))
    path = movement_plan(p)
    world = run_world(p, path, t_end=6.0, lay=LAY)
    line = laid_shape(p, LAY, np.asarray(path.position(0.0)))
    return p, path, world, line


def _mean_distance(world, run, t0: float, t1: float) -> float:
    """Mean distance [m] of the world's masses from the model's centreline, frames every
    0.1 s in [t0, t1)."""
    times = np.arange(t0, t1, 0.1)
    lines = polylines_at(run, times)
    out = []
    for k, t in enumerate(times):
        nodes = world.nodes(int(np.clip(np.searchsorted(world.t, t), 0, world.t.size - 1)))
        a, seg = lines[k][:-1], np.diff(lines[k], axis=0)
        rel = nodes[:, None, :] - a[None]
        s = np.clip((rel * seg).sum(2) / (seg ** 2).sum(1), 0.0, 1.0)
        d = rel - s[..., None] * seg
        out.append(np.sqrt((d ** 2).sum(2).min(axis=1)).mean())
    return float(np.mean(out))


def test_the_laid_sheet_released_follows_the_world_where_the_settled_drape_cannot(released):
    """Started from the world's own laid sheet (its shape and length), the model is the
    world's sheet at t = 0 (the first frame) and stays closer through the fall (0-0.5 s:
    0.39 mm mean distance against the settled drape's 0.84 mm, measured); once the sheet has
    fallen (1-6 s) the two starts agree to 0.01 mm and both lie within 0.1 mm of the world."""
    p, path, world, line = released
    laid = run_scenario(p, path, t_end=6.0, laid=LaidSheet(line, _polyline_length(line)))
    settled = run_scenario(p, path, t_end=6.0)
    assert _mean_distance(world, laid, 0.0, 0.05) < 5e-5
    assert _mean_distance(world, settled, 0.0, 0.05) > 5e-4
    assert _mean_distance(world, laid, 0.0, 0.5) < 0.5 * _mean_distance(world, settled, 0.0, 0.5)
    late_l = _mean_distance(world, laid, 1.0, 6.0)
    late_s = _mean_distance(world, settled, 1.0, 6.0)
    assert late_l < 1e-4 and late_s < 1e-4 and abs(late_l - late_s) < 2e-5


def test_the_records_say_the_sheet_was_laid_and_how_long_it_is(released):
    """From the record alone: laid (it moves many noise units before the tool touches), its
    length within 0.6 mm of the world's laid length (3 of the measured spread 0.15-0.19 mm,
    bias -0.04 to -0.10 mm), a standard error of that size, no contact before 20 s."""
    p, path, world, line = released
    true = _polyline_length(line)
    for seed in range(3):
        rec = measure_world(world, path, SensorParams(frame_dropout=0.0),
                            np.random.default_rng(seed))
        st = ist.estimate(replace(rec, scenario=p), "auto")
        assert st.mode == "laid" and st.motion > ist.MOVING
        assert st.t0 == 0.0 and st.contact_time > 5.0
        assert abs(st.length - true) < 6e-4
        assert 5e-5 < st.length_sd < 5e-4
        assert 1.5e-4 < st.noise < 2.6e-4          # the camera's 0.2 mm
        sheet = st.laid(p)
        assert sheet.rest_length == pytest.approx(st.length, abs=1e-12)


def test_a_settled_sheet_stays_settled():
    """Records of the model itself (its drape settled before t = 0): the sheet does not move
    beyond the noise before the tool touches, so ``auto`` keeps the settled drape."""
    p = CellParams()
    p = replace(p, sheet=replace(p.sheet, n_masses=31),
                movement=replace(p.movement, number=4, process_time=30.0))
    rec, _ = synthesize_record(p, seed=3)
    st = ist.estimate(rec, "auto")
    assert st.motion < ist.MOVING and st.mode == "settled"
    assert st.laid(p) is None


def test_pooling_takes_one_mode_and_keeps_each_length():
    """The median motion decides the mode for all; each laying keeps its own length (a sheet
    laid over a tool in its way is laid longer)."""
    base = ist.InitialState("laid", 0.0, np.zeros((3, 2)), 0.105, 2e-4, 2e-4, 5.0, 1.0, 0.006)
    states = [replace(base, mode="settled" if m < ist.MOVING else "laid", length=L, motion=m)
              for L, m in ((0.105, 5.0), (0.1062, 1.0), (0.1049, 4.0))]
    pooled = ist.pool(states, auto=True)
    assert [s.mode for s in pooled] == ["laid"] * 3
    assert [s.length for s in pooled] == [0.105, 0.1062, 0.1049]
    quiet = ist.pool([replace(s, motion=1.0) for s in states], auto=True)
    assert all(s.mode == "settled" for s in quiet)
    # one record that falls far (laid over the tool) says the sheets were laid and let go
    one = ist.pool([replace(s, motion=m) for s, m in zip(states, (1.2, 27.0, 1.5))], auto=True)
    assert all(s.mode == "laid" for s in one)
    calm = ist.pool([replace(s, motion=m) for s, m in zip(states, (1.2, 9.0, 1.5))], auto=True)
    assert all(s.mode == "settled" for s in calm)


def test_an_unknown_initial_state_is_a_one_line_error():
    p = CellParams()
    p = replace(p, sheet=replace(p.sheet, n_masses=15),
                movement=replace(p.movement, process_time=20.0))
    rec, _ = synthesize_record(p, seed=1)
    with pytest.raises(ValueError, match="initial state 'dropped': expected one of auto"):
        ist.estimate(rec, "dropped")


def test_each_record_s_first_seconds_fit_its_rest_length(released):
    """The rest length fitted on the record's first seconds after the fall
    (:mod:`~rheo_shaping.diagnosis.laid_length`) comes back to the world's own, also from a
    reading 2 mm off (the misread first frames of issue 26's floor calibration were 0.4-1.3
    mm off, a sheet laid over the tool 2-2.5 mm longer than the others).  Measured: 0.12-0.14
    mm short of the world's (its form: the fall's ringing, the soft contact) from readings 0
    and +-2 mm off, on three noise draws."""
    from rheo_shaping.diagnosis.compare import RecordData
    from rheo_shaping.diagnosis.laid_length import fit_offsets, with_offsets
    p, path, world, line = released
    true = _polyline_length(line)
    errors = []
    for seed, misread in ((0, 0.0), (1, 2e-3), (2, -2e-3)):
        rec = replace(measure_world(world, path, SensorParams(frame_dropout=0.0),
                                    np.random.default_rng(seed)), scenario=p)
        d = RecordData.of(rec, "auto")
        d = replace(d, initial=replace(d.initial, length=d.initial.length + misread))
        (offset,) = fit_offsets([d], [p])
        (fitted,) = with_offsets([d], [offset])
        errors.append(fitted.initial.rest(p) - true)
    assert max(abs(e) for e in errors) < 3e-4
    assert max(errors) - min(errors) < 1e-4        # the same length from any reading


def test_a_candidate_is_judged_on_holdout_records_with_lengths_fitted_under_its_own_cell(
        released):
    """A laid record's rest length is a nuisance fitted under the cell being judged
    (:func:`~rheo_shaping.diagnosis.holdout_lengths.holdout_lengths`): a candidate whose top bond
    moved 1 mm from the cell the record's length was fitted for is judged with the length
    its own cell gives, and misfits the holdout record less than with the stale one."""
    from functools import partial
    from types import SimpleNamespace
    from rheo_shaping.diagnosis.baseline import SHEET
    from rheo_shaping.diagnosis.candidates import Explanation
    from rheo_shaping.diagnosis.holdout_lengths import holdout_lengths
    from rheo_shaping.diagnosis.compare import RecordData
    from rheo_shaping.diagnosis.context import FitContext, Group
    from rheo_shaping.diagnosis.evaluate import Runner, Task
    from rheo_shaping.diagnosis.laid_length import fit_offsets, with_offsets
    p, path, world, _ = released
    rec = replace(measure_world(world, path, SensorParams(frame_dropout=0.0),
                                np.random.default_rng(3)), scenario=p)
    d = RecordData.of(rec, "auto")
    (d,) = with_offsets([d], fit_offsets([d], [p]))     # the length under the written cell
    u = np.zeros(len(SHEET) + 6)
    u[[k.name for k in SHEET].index("sheet.top_bond_x")] = 1.0
    params = partial(FitContext.params, SimpleNamespace(sheet_lim=1.0))
    run = Runner(jobs=1)
    (nominal,) = run([Task(d, p)])
    H = Group.of([d], 2e-4, 5e-3, [nominal])
    ctx = SimpleNamespace(H=H, hold_d=[d], fit_d=[], data=[d], nf=0, n_s=len(SHEET),
                          params=params, run=run)
    c = Explanation(("mass_error",), {"mass_error": (0.0,)}, 1.0, checked=True, baseline_u=u)
    (stale,) = run([Task(d, params(d, u[:len(SHEET)]))])
    J_stale = H.J(H.z([stale]))
    holdout_lengths([c], ctx)
    assert c.J_holdout < 0.9 * J_stale          # measured: 1.30 against 1.87
    # the same record also fitted: the shift its window asks under the candidate's cell is
    # asked by every record alike, which the candidate's knobs carry on the whole records;
    # the holdout does not take it alone (holdout_lengths.common_shift)
    ctx2 = SimpleNamespace(H=H, hold_d=[d], fit_d=[d], data=[d, d], nf=1, n_s=len(SHEET),
                           params=params, run=run)
    c2 = Explanation(("mass_error",), {"mass_error": (0.0,)}, 1.0, checked=True,
                     baseline_u=u)
    holdout_lengths([c2], ctx2)
    assert c2.J_holdout == pytest.approx(J_stale, rel=1e-9)


def test_auto_reading_settled_takes_the_start_whose_baseline_fits_better():
    """A sheet laid close to its resting shape hardly moves before the tool touches, as a
    settled one does, so ``auto`` reads both as settled; it then fits the baseline from either
    start and takes the one that fits the fit records better (docs/diagnosis.md, Initial
    state).  On records of the model itself, settled before t = 0, the two starts fit alike
    (a settled sheet is a laid one that does not move): nothing rides on the choice.  A
    dynamic-world laying whose records moved 4.8, 2.0 and 1.6 noise units (median below
    ``MOVING``) fits far better from its first frames."""
    from rheo_shaping_validation.benchmark import base_cell, make_case
    from rheo_shaping.diagnosis.engine import diagnose
    from rheo_shaping.diagnosis.report_text import markdown
    p = CellParams()
    p = replace(p, sheet=replace(p.sheet, n_masses=15))
    own = [synthesize_record(replace(p, movement=replace(p.movement, number=m,
                                                         process_time=30.0)), seed=m)[0]
           for m in (4, 1)]
    d = diagnose(own, library=(), jobs=1, initial_state="auto", floor="numerics")
    both = d.initial_state["compared"]
    assert both["laid_J"] == pytest.approx(both["settled_J"], rel=0.01)   # measured 0.2 %
    assert d.J_base == min(both.values())
    assert d.initial_state["mode"] == min(both, key=both.get).removesuffix("_J")
    case = make_case(0, "none", 7, base_cell(15, 40.0), world="dynamic")
    assert {s.mode for s in ist.pool([ist.estimate(r, "auto") for r in case["records"]],
                                     True)} == {"settled"}
    d = diagnose(case["records"][:2], case["records"][2:], library=(), jobs=1,
                 initial_state="auto", floor="numerics")
    both = d.initial_state["compared"]
    assert d.initial_state["mode"] == "laid" and d.J_base == both["laid_J"]
    assert both["laid_J"] - 1.0 < 0.8 * (both["settled_J"] - 1.0)  # measured 0.73 vs 1.67
    text = markdown(d, {})
    assert (f"settled drape leaves J = {both['settled_J']:.3f}" in text
            and f"released J = {both['laid_J']:.3f}: the models start laid" in text)
