"""The sim-to-real diagnosis on stand-in records: exact comparison chain, noise estimate,
where, a right verdict with its interval, 'none' and 'unexplained', the commands."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.cli import main
from rheo_shaping.diagnosis.compare import RecordData, noise_level, residuals, simulate
from rheo_shaping.diagnosis.engine import diagnose
from rheo_shaping.diagnosis.where import PHASES, phases
from rheo_shaping.effects import EFFECTS
from rheo_shaping.measurement import MeasurementParams, synthesize_record
from rheo_shaping.params import CellParams
from rheo_shaping.records import write_record


def cell(movement: int, process_time: float = 70.0, **effects) -> CellParams:
    p = CellParams()
    p = replace(p, movement=replace(p.movement, number=movement, process_time=process_time))
    for name, values in effects.items():
        p = EFFECTS[name].apply(p, values)
    return p


def records(seed: int, movements=(1, 4, 2), **effects):
    return [synthesize_record(cell(m, **effects), seed=seed + i, name=f"m{m}")[0]
            for i, m in enumerate(movements)]


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
        rec, _ = synthesize_record(cell(4), MeasurementParams(profile_noise=sigma, wrench_noise=0.02), seed=2)
        data = RecordData.of(rec)
        res = residuals(data, simulate(rec.scenario, data))
        assert noise_level(res.profile, data.point_frame) == pytest.approx(sigma, rel=0.1)
        assert noise_level(res.force[:, 0]) == pytest.approx(0.02, rel=0.1)


def test_phases_follow_the_movement():
    rec, run = synthesize_record(cell(1, process_time=120.0), seed=3)
    data = RecordData.of(rec)
    labels = phases(data, simulate(rec.scenario, data))
    seen = [PHASES[i] for i in labels]
    order = [p for i, p in enumerate(seen) if i == 0 or p != seen[i - 1]]
    assert order[0] == "approach"
    assert "forced deformation" in order and "dwell" in order
    assert order.index("forced deformation") < order.index("dwell")
    t_dwell = rec.profile_t[labels == PHASES.index("dwell")]
    assert t_dwell.min() > 10.0 and np.ptp(t_dwell) == pytest.approx(30.0, abs=3.0)   # the 30 s stop


def test_no_effect_is_diagnosed_as_none():
    d = diagnose(records(10)[:2], records(10)[2:], jobs=2)
    assert d.verdict == "none"
    assert d.J0 < 1.06


def test_tool_offset_is_named_recovered_and_shrinks_the_holdout_gap():
    true = (-1.2e-3, 1.0e-3)
    recs = records(20, tool_offset=true)
    d = diagnose(recs[:2], recs[2:], library=("tool_offset", "mass_error", "kelvin_c1"), jobs=2)
    assert d.verdict == "tool_offset"
    fitted = d.verdict_fit.values["tool_offset"]
    for v, t, (lo, hi) in zip(fitted, true, d.verdict_fit.interval["tool_offset"]):
        assert abs(v - t) < 0.25e-3
        assert lo <= t <= hi
    assert d.gap_after["holdout"]["shrink"] >= 0.7
    top = d.where[0]
    assert top["relative"] > 1.0
    out = d.to_json()
    assert {"verdict", "effects", "where", "gap_before", "gap_after"} <= set(out)
    assert out["effects"][0]["name"] == "tool_offset"
    assert {"fit", "holdout"} <= set(out["gap_before"])


def test_an_effect_outside_the_library_is_unexplained():
    recs = records(30, friction_mould=(0.5,))
    d = diagnose(recs[:2], recs[2:], library=("tool_offset", "mass_error"), jobs=2)
    assert d.verdict == "unexplained"


def test_diagnose_command(tmp_path, capsys):
    recs = records(40, movements=(4, 1))
    for r in recs:
        write_record(r, tmp_path / r.name)
    out = tmp_path / "report"
    code = main(["diagnose", str(tmp_path / "m4"), "--holdout", str(tmp_path / "m1"), "--out", str(out), "--json"])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert result["verdict"] == "none"
    assert (out / "report.md").exists() and (out / "residual_map.png").stat().st_size > 10_000
    assert main(["diagnose", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert "missing: not a directory" in err and "Traceback" not in err
    assert main(["diagnose", str(tmp_path / "m4"), "--effects", "friction,bending"]) == 2
    assert "unknown effect 'friction'" in capsys.readouterr().err
