"""The sim-to-real diagnosis: exact comparison chain, noise estimate, phases, the balanced misfit
and its bounded fit, and verdicts on records made without the inverse crime (a finer true chain,
half steps, softer contact, the written scenario and the measurement chain off within
tolerance)."""
from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.cli import main
from rheo_shaping.params.config import load_cell
from rheo_shaping.diagnosis import stats
from rheo_shaping.diagnosis.baseline import CHAIN, SHEET
from rheo_shaping_validation.benchmark import base_cell, make_case
from rheo_shaping.diagnosis.compare import RecordData, noise_level, residuals, simulate
from rheo_shaping.diagnosis import Verdict, diagnose
from rheo_shaping.diagnosis.evaluate import Task, run_batch
from rheo_shaping.diagnosis.linear import Solver, Stack
from rheo_shaping.diagnosis.where import PHASES, phases
from rheo_shaping.sheet.effects import EFFECTS
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams
from rheo_shaping.params.cell import CellParams
from rheo_shaping.records.bag import write_record

#: The benchmark's configuration (the gap test's null is calibrated on it, docs/diagnosis.md).
N_MASSES, PROCESS_TIME = 31, 70.0


def cell(movement: int, process_time: float = 70.0, n_masses: int = 63, **effects) -> CellParams:
    p = CellParams()
    p = replace(p, sheet=replace(p.sheet, n_masses=n_masses),
                movement=replace(p.movement, number=movement, process_time=process_time))
    for name, values in effects.items():
        p = EFFECTS[name].apply(p, values)
    return p


def test_comparison_chain_is_exact_without_noise():
    ms = MeasurementParams(profile_noise=0.0, pose_noise=0.0, wrench_noise=0.0)
    rec, _ = synthesize_record(cell(4), ms, seed=1)
    data = RecordData.of(rec)
    res = residuals(data, simulate(rec.scenario, data))
    # the only difference: the model follows the measured pose smoothed over 0.4 s
    assert np.sqrt(np.mean(res.profile ** 2)) < 2e-5
    assert np.sqrt(np.mean(res.force ** 2)) < 1e-3      # a tenth of the default load-cell noise


def test_noise_estimate_recovers_the_injected_noise():
    for sigma in (1e-4, 5e-4):
        ms = MeasurementParams(profile_noise=sigma, wrench_noise=0.02)
        rec, _ = synthesize_record(cell(4), ms, seed=2)
        data = RecordData.of(rec)
        res = residuals(data, simulate(rec.scenario, data))
        assert noise_level(res.profile, data.point_frame) == pytest.approx(sigma, rel=0.1)
        assert noise_level(res.force[:, 0]) == pytest.approx(0.02, rel=0.1)


def test_a_noise_free_force_is_weighed_at_the_floor_not_ignored():
    """A simulator's noise-free wrench shows no noise in its second differences: the force is
    weighed with MIN_FORCE_NOISE (1 mN), not with the 1 N of records without a force (the gap
    watch's diagnoses of simulated cells ignored the force so)."""
    from rheo_shaping.diagnosis.stages import MIN_FORCE_NOISE
    ms = MeasurementParams(wrench_noise=0.0)
    rec, _ = synthesize_record(cell(4, process_time=30.0, n_masses=15), ms, seed=3)
    d = diagnose([rec], library=(), jobs=1, floor="numerics", initial_state="settled")
    assert d.noise.force_N == MIN_FORCE_NOISE
    assert d.noise.profile_m == pytest.approx(ms.profile_noise, rel=0.15)
    no_force, _ = synthesize_record(cell(4, process_time=30.0, n_masses=15),
                                    replace(ms, wrench=False), seed=3)
    assert diagnose([no_force], library=(), jobs=1,
                    floor="numerics", initial_state="settled").noise.force_N == 1.0


def test_phases_follow_the_movement():
    rec, run = synthesize_record(cell(1, process_time=120.0, n_masses=31), seed=3)
    data = RecordData.of(rec)
    labels = phases(data, simulate(rec.scenario, data))
    seen = [PHASES[i] for i in labels]
    order = [p for i, p in enumerate(seen) if i == 0 or p != seen[i - 1]]
    assert order[0] == "approach"
    assert "forced deformation" in order and "dwell" in order
    assert order.index("forced deformation") < order.index("dwell")
    t_dwell = rec.profile_t[labels == PHASES.index("dwell")]
    # the 30 s stop
    assert t_dwell.min() > 10.0 and np.ptp(t_dwell) == pytest.approx(30.0, abs=3.0)


def test_balanced_misfit_and_chain_columns_are_exact():
    """J of the stacked vector is (J_p + J_f) / 2; a vision offset and a load-cell bias are
    linear in the residuals to first order: the chain's columns recover them (no noise)."""
    ms = MeasurementParams(profile_noise=0.0, pose_noise=0.0, wrench_noise=0.0)
    rec, _ = synthesize_record(cell(4, n_masses=15, process_time=40.0), ms, seed=4)
    off, bias = np.array([4e-4, -3e-4]), np.array([0.0, 0.02])
    clean = RecordData.of(rec)
    rec = replace(rec, profiles=tuple(f + off for f in rec.profiles),
                  wrench_xz=rec.wrench_xz + bias)
    data = RecordData.of(rec)
    o, oc = run_batch([Task(data, rec.scenario), Task(clean, rec.scenario)])
    st = Stack([data.point_frame], [True], 1e-4, 1e-2)
    st.set_force_count([o])
    z = st.vec([o])
    J_p = np.mean(o.profile ** 2) / 1e-4 ** 2
    J_f = np.mean(o.force ** 2) / 1e-2 ** 2
    assert z @ z == pytest.approx(0.5 * (J_p + J_f), rel=1e-12)
    A = st.chain_columns([o])
    lim = np.array([k.limit for k in CHAIN])
    u, J = Solver(A).solve(z, -lim, lim)
    fitted = u * np.array([k.tolerance for k in CHAIN])
    assert fitted[0] == pytest.approx(off[0], abs=2e-5)
    assert fitted[1] == pytest.approx(off[1], abs=2e-5)
    assert fitted[3] == pytest.approx(bias[1], abs=1e-4) and abs(fitted[2]) < 1e-4
    zc = st.vec([oc])
    assert z @ z > 10 * (zc @ zc)
    # what is left is below a tenth of the noise variance (foot points move along the bends)
    assert J < 0.1


def test_effective_sample_size():
    rng = np.random.default_rng(5)
    white = rng.normal(size=4000)
    frames = np.repeat(np.arange(40), 100)
    assert stats.n_eff_profile(white, frames) == pytest.approx(4000, rel=0.1)
    smooth = np.repeat(rng.normal(size=40), 100)   # one value per frame, white across frames
    assert stats.n_eff_profile(smooth, frames) < 0.05 * 4000
    ar = np.zeros(20000)
    for i in range(1, ar.size):
        ar[i] = 0.9 * ar[i - 1] + rng.normal()
    n = stats.n_eff_force(np.c_[ar, ar])
    assert n == pytest.approx(2 * 20000 * 0.1 / 1.9, rel=0.15)


def _case(kind: str, index: int, seed: int):
    return make_case(index, kind, seed, base_cell(N_MASSES, PROCESS_TIME))


def test_effect_free_records_from_a_finer_chain_give_none():
    case = _case("none", 1, 7)
    assert case["records"][0].scenario.sheet.n_masses == N_MASSES
    d = diagnose(case["records"][:2], case["records"][2:], jobs=2,
                 floor="numerics", initial_state="settled")
    assert d.J0 > 1.2                      # the written scenario alone does not fit ...
    assert d.J_base - 1.0 < 0.5 * (d.J0 - 1.0)   # ... the calibrated baseline does
    assert d.verdict == "none" and d.p_gap > stats.ALPHA
    for name, b in d.baseline.items():
        if name in {k.name for k in SHEET}:
            assert abs(b["u"]) <= 1.0 + 1e-9


def test_tool_offset_is_named_with_its_strength_and_shrinks_the_holdout_gap():
    case = _case("single", 4, 3)
    rec = case["records"]
    d = diagnose(rec[:2], rec[2:], library=("tool_offset", "mass_error", "kelvin_c1"), jobs=2,
                 floor="numerics", initial_state="settled")
    true = case["truth"][0]
    assert true[0] == "tool_offset"
    assert d.verdict is Verdict.EFFECT and d.named == ("tool_offset",)
    assert d.verdict_name == "tool_offset"
    assert d.verdict_fit.p <= stats.ALPHA and d.p_gap <= stats.ALPHA
    for v, t in zip(d.verdict_fit.values["tool_offset"], true[1]):
        assert abs(v - t) < 0.3e-3
    assert d.gap_after.holdout.shrink >= 0.7
    out = d.to_json()
    keys = {"verdict", "verdict_p", "p_gap", "side", "baseline", "effects", "gap_baseline"}
    assert keys <= set(out)


def test_an_effect_outside_the_library_is_unexplained_with_a_signature():
    case = _case("single", 0, 3)                     # friction_mould
    assert case["truth"][0][0] == "friction_mould"
    rec = case["records"]
    d = diagnose(rec[:2], rec[2:], library=("tool_offset", "mass_error"), jobs=2,
                 floor="numerics", initial_state="settled")
    assert d.p_gap <= stats.ALPHA
    assert d.verdict == "unexplained"
    sig = d.signature
    assert {"observables", "where", "when", "trend", "proportional_to", "causes"} <= set(sig)
    # every kind once, ranked by score after any library effect that imitates the gap
    from rheo_shaping.diagnosis.signature import CAUSES, SUBSTITUTE_SHARE
    causes = sig["causes"]
    assert sorted(c["kind"] for c in causes) == sorted(CAUSES)
    lead = [c for c in causes if (c["substitute_share"] or 0.0) >= SUBSTITUTE_SHARE]
    assert causes[:len(lead)] == lead
    rest = [c["score"] for c in causes[len(lead):]]
    assert rest == sorted(rest, reverse=True)


def test_diagnose_command_and_write_scenario(tmp_path, capsys):
    case = _case("none", 5, 11)
    for r in case["records"][:2]:
        write_record(r, tmp_path / r.name)
    a, b = (tmp_path / r.name for r in case["records"][:2])
    out, scen = tmp_path / "report", tmp_path / "corrected.yaml"
    # records of the model itself (a finer chain): its floor is numerics, its sheet settled
    code = main(["diagnose", str(a), "--holdout", str(b), "--out", str(out), "--json",
                 "--write-scenario", str(scen), "--floor", "numerics",
                 "--initial-state", "settled"])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert result["verdict"] == "none"
    assert (out / "report.md").exists() and (out / "residual_map.png").stat().st_size > 10_000
    assert "## Baseline" in (out / "report.md").read_text()
    corrected = load_cell(scen)          # simulate / reproduce --params / planner read it
    assert corrected.sheet.n_masses == N_MASSES
    assert set(result["process"]) == {"nominal", "corrected"}
    assert math.isfinite(result["process"]["corrected"]["F_max"])
    assert main(["diagnose", str(a), "--write-scenario", str(scen)]) == 2    # never overwritten
    assert "exists" in capsys.readouterr().err
    assert main(["diagnose", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert "missing: not a directory" in err and "Traceback" not in err
    assert main(["diagnose", str(a), "--effects", "friction,bending"]) == 2
    assert "unknown effect 'friction'" in capsys.readouterr().err


def test_numerics_allowance_is_the_added_refined_error_and_never_a_large_part_of_the_gap():
    """The allowance is NUMERICS_FACTOR x the misfit of the candidate's refinement change
    less the baseline's (J_num_added), capped at GAP_SHARE of the baseline's excess; the
    totals J_num do not enter (docs/diagnosis.md)."""
    from rheo_shaping.diagnosis.candidates import Explanation
    from rheo_shaping.diagnosis.adequacy import adequate
    from rheo_shaping.diagnosis.check import GAP_SHARE, NUMERICS_FACTOR, ORDER
    assert NUMERICS_FACTOR == pytest.approx((1.0 / (1.0 - 2.0 ** -ORDER)) ** 2)
    base = Explanation((), {}, 2.0, J_num=0.05, J_num_holdout=0.05)    # excess 1.0
    J_bh = 2.0

    def cand(J, added, J_num=0.05):
        return Explanation(("kelvin_c1",), {"kelvin_c1": (800.0,)}, J, J_holdout=J,
                           checked=True, J_num=J_num, J_num_holdout=J_num,
                           J_num_added=added, J_num_added_holdout=added)
    q, qh = stats.null_quantile(), stats.null_quantile(True)
    # within the null: adequate without any numerics
    assert adequate(cand(1.0 + 0.5 * min(q, qh), math.nan), J_bh, True, base)
    # leaves 0.2: refused with nothing added, adequate with just enough added numerics
    assert not adequate(cand(1.2, 0.0), J_bh, True, base)
    need = (0.2 - min(q, qh)) / NUMERICS_FACTOR
    assert not adequate(cand(1.2, 0.9 * need), J_bh, True, base)
    assert adequate(cand(1.2, 1.1 * need), J_bh, True, base)
    # the same totals as the baseline's, a change of another shape: the added part counts
    assert adequate(cand(1.2, 1.1 * need, J_num=base.J_num), J_bh, True, base)
    # larger totals with nothing added grant nothing
    assert not adequate(cand(1.2, 0.0, J_num=10.0), J_bh, True, base)
    # without the baseline's refined run beside it, no allowance
    assert not adequate(cand(1.2, 1.1 * need), J_bh, True, None)
    # whatever its numerics, a candidate never leaves more than GAP_SHARE of the gap
    assert not adequate(cand(1.0 + max(q, qh) + GAP_SHARE + 0.01, 10.0), J_bh, True, base)
    assert adequate(cand(1.0 + min(q, qh) + GAP_SHARE - 0.01, 10.0), J_bh, True, base)
    # the holdout records must improve on the baseline
    assert not adequate(cand(1.2, 10.0), 1.1, True, base)


def test_a_strong_kelvin_creep_is_named_through_its_own_jacobian_and_numerics():
    """c1 = 785 N s/m (true chain 63 masses, diagnosis 31): what the right effect leaves
    exceeds the effect-free null; its refined run shows the leftover is the model's own
    discretisation error at the effect, and the value lies within its interval."""
    from rheo_shaping.diagnosis.check import NUMERICS_FACTOR
    case = _case("single", 34, 1)
    (name, (true,)), = case["truth"]
    assert name == "kelvin_c1"
    rec = case["records"]
    d = diagnose(rec[:2], rec[2:], library=("kelvin_c1", "power_law", "mass_error"), jobs=2,
                 floor="numerics", initial_state="settled")
    assert d.verdict_name == "kelvin_c1"
    vf = d.verdict_fit
    assert vf.J - 1.0 > stats.null_quantile()             # the null alone would refuse it
    assert vf.J_num > d.numerics_base.J_num                # the effect raises the numerics
    # what it adds is the misfit of the difference of the two changes: a norm, so it lies
    # between the difference and the sum of their roots (J is quadratic)
    r_c, r_0, r_a = (math.sqrt(x) for x in (vf.J_num, d.numerics_base.J_num, vf.J_num_added))
    assert abs(r_c - r_0) - 1e-12 <= r_a <= r_c + r_0 + 1e-12
    assert vf.J - 1.0 <= stats.null_quantile() + NUMERICS_FACTOR * vf.J_num_added
    assert vf.J - 1.0 <= 0.25 * (d.J_base - 1.0)
    (value,), ((lo, hi),) = vf.values[name], vf.interval[name]
    assert value == pytest.approx(true, rel=0.1)
    assert lo <= true <= hi


def test_replay_null_is_the_stored_null_plus_each_draw():
    """The gap test's null for a Kelvin cell: every sum of a stored value and a draw of the
    model's own replay misfit (exact counts)."""
    x = stats._null_sample()["fit"]
    c = 0.3
    assert stats.null_quantile(shift=np.array([c])) == pytest.approx(stats.null_quantile() + c)
    for e in (x[10], x[100], x[-3]):
        assert stats.gap_p_value(e + c, shift=[c]) == stats.gap_p_value(e)
    # two draws, 0 and c: the null is the stored one twice, once shifted by c
    e = x[-1] + 1e-9                          # above every stored value, below every shifted one
    assert stats.gap_p_value(e, shift=[0.0, c]) == pytest.approx(
        (1 + x.size) / (2 * x.size + 1))
    assert stats.gap_p_value(e) == pytest.approx(1 / (x.size + 1))


def test_pose_noise_estimate_recovers_the_reported_pose_noise():
    from rheo_shaping.diagnosis.replay import pose_noise
    for sigma in (0.0, 2e-5, 1e-4):
        ms = MeasurementParams(pose_noise=sigma)
        rec, _ = synthesize_record(cell(4, PROCESS_TIME, N_MASSES), ms, seed=3)
        assert pose_noise(rec) == pytest.approx(sigma, rel=0.05, abs=1e-7)


def test_a_kelvin_cell_round_trips_to_none_and_still_sees_a_real_gap():
    """Records made from a written cell with a strong Kelvin creep (c1 = 441 N s/m, the
    diagnosis's own chain and steps, default sensors): the stored null alone refuses them
    (the replay of a noisy pose through the dashpot), the null plus the model's own replay
    misfit gives `none`; a tool offset of 1.5 mm on the same cell is still a gap."""
    written = cell(1, PROCESS_TIME, N_MASSES, kelvin_c1=(441.0,))

    def records(truth):
        out = []
        for m in (4, 2, 1):
            t = replace(truth, movement=replace(truth.movement, number=m))
            w = replace(written, movement=replace(written.movement, number=m))
            rec = synthesize_record(t, seed=500 + m, name=f"m{m}")[0]
            out.append(replace(rec, scenario=w))
        return out
    rec = records(written)
    d = diagnose(rec[:2], rec[2:], jobs=2, floor="numerics", initial_state="settled")
    assert stats.gap_p_value(d.J_base - 1.0) <= stats.ALPHA        # the stored null refuses
    assert d.J_replay[0] is not None and d.J_replay[0].size == 8
    assert d.verdict == "none" and d.p_gap > stats.ALPHA
    off = EFFECTS["tool_offset"].apply(written, (1.5e-3, 0.0))
    rec = records(off)
    d = diagnose(rec[:2], rec[2:], library=("tool_offset", "mass_error"), jobs=2,
                 floor="numerics", initial_state="settled")
    assert d.p_gap <= stats.ALPHA and d.verdict_name == "tool_offset"


def test_a_held_baseline_keeps_the_sheet_knobs_as_written():
    """``baseline="held"`` (the gap watch's question: what changed since the model cell was
    commissioned) fits the measurement chain only: a k1 8 % off the written one, which the
    calibrated baseline takes back (u near +0.8 of its 10 % tolerance), stays in the held
    baseline's remainder."""
    written = cell(4, process_time=70.0, n_masses=15)
    truth = replace(written, material=replace(written.material, k1=1.08 * written.material.k1))
    rec, _ = synthesize_record(truth, MeasurementParams(wrench_noise=0.003), seed=5)
    rec = replace(rec, scenario=written)
    cal = diagnose([rec], library=(), jobs=1, floor="numerics", initial_state="settled")
    held = diagnose([rec], library=(), jobs=1, baseline="held",
                    floor="numerics", initial_state="settled")
    assert cal.baseline["material.k1"]["u"] == pytest.approx(0.8, abs=0.25)
    assert cal.baseline_mode == "calibrated" and held.baseline_mode == "held"
    assert all(held.baseline[k.name]["u"] == 0.0 for k in SHEET)
    assert held.baseline["material.k1"]["value"] == written.material.k1
    # the held baseline leaves the k1 error, the calibrated one takes it
    assert held.J_base - 1.0 > 2.0 * max(cal.J_base - 1.0, 0.05)
    assert held.to_json()["baseline_mode"] == "held"
    with pytest.raises(ValueError, match="baseline 'loose': expected one of calibrated, held"):
        diagnose([rec], library=(), jobs=1, baseline="loose")
