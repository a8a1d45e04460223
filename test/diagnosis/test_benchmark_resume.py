"""An interrupted diagnosis benchmark goes on where it stopped: each finished case is kept
in a JSON-lines file, and a file of another benchmark is refused (no ROS)."""
from __future__ import annotations

import json
from dataclasses import replace

import pytest

from rheo_shaping_validation.benchmark import (DRAWS, against_target, base_cell, run_benchmark,
                                               summarise)
from rheo_shaping_validation.benchmark.run import _case_task
from rheo_shaping_validation.benchmark.checkpoint import append_partial, read_partial


def test_cases_already_done_are_not_run_again_and_new_ones_are_kept(tmp_path):
    part = tmp_path / "bench.json.partial.jsonl"
    kw = dict(n_masses=7, process_time=20.0, kinds=("none",), seed=5)
    first = run_benchmark(1, partial=str(part), jobs=1, **kw)
    assert first["resumed_cases"] == 0 and len(first["case_results"]) == 1
    lines = part.read_text().splitlines()
    assert len(lines) == 1
    # mark the kept case: a resumed run takes it from the file, not from a new diagnosis
    entry = json.loads(lines[0])
    entry["row"]["marker"] = "from the file"
    part.write_text(json.dumps(entry) + "\n")
    second = run_benchmark(2, partial=str(part), jobs=1, **kw)
    assert second["resumed_cases"] == 1
    rows = second["case_results"]
    assert [r["index"] for r in rows] == [0, 1]
    assert rows[0]["marker"] == "from the file" and "marker" not in rows[1]
    assert len(part.read_text().splitlines()) == 2


def test_a_partial_file_of_another_benchmark_is_refused(tmp_path):
    part = tmp_path / "p.jsonl"
    append_partial(str(part), {"seed": 1}, {"index": 0})
    assert read_partial(str(part), {"seed": 1}) == {0: {"index": 0}}
    with pytest.raises(ValueError, match="a case of another benchmark"):
        read_partial(str(part), {"seed": 2})
    part.write_text(part.read_text() + '{"key": {"seed": 1}, "row": {"ind')   # cut short
    assert read_partial(str(part), {"seed": 1}) == {0: {"index": 0}}


def test_a_case_whose_every_draw_tears_is_left_out_and_said_not_a_crash(tmp_path):
    # a sheet that breaks at 1 mN: every draw's first record tears it
    base = base_cell(7, 20.0)
    base = replace(base, material=replace(base.material, F_break=1e-3))
    part = tmp_path / "b.json.partial.jsonl"
    key = {"seed": 3}
    row = _case_task({"seed": 3, "base": base, "pattern": ("single",), "jobs": 1,
                      "partial": str(part), "key": key}, 0)
    assert set(row) == {"index", "kind", "no_case"}
    assert f"no valid single case in {DRAWS} draws ({DRAWS} tore the sheet" in row["no_case"]
    assert read_partial(str(part), key) == {0: row}          # kept: a resumed run skips it
    # the benchmark counts it apart: not a case of the summary, listed as not drawn
    kw = dict(n_masses=7, process_time=20.0, kinds=("single",), seed=3)
    real_key = {"seed": 3, "world": "finer-chain", "n_masses": 7, "process_time_s": 20.0,
                "floor": "numerics", "initial_state": "settled", "pattern": ["single"]}
    part2 = tmp_path / "c.json.partial.jsonl"
    append_partial(str(part2), real_key, row)
    out = run_benchmark(1, partial=str(part2), jobs=1, **kw)
    assert out["cases"] == 0 and out["case_results"] == []
    assert out["undrawn_cases"] == [row]


def test_the_summary_counts_none_as_the_verdict_none_and_names_apart():
    # four effect-free cases: `none`, `none`, `unexplained`, a library name
    rows = [{"index": i, "kind": "none", "verdict": v, "correct": v in ("none", "unexplained"),
             "p_gap": 0.5, "simulations": 1, "baseline_error_u": {}}
            for i, v in enumerate(("none", "none", "unexplained", "bending"))]
    s = summarise(rows, 0.0)
    assert s["no_effect_none_rate"] == 0.5                   # the verdict itself
    assert s["no_effect_library_name_rate"] == 0.25
    assert s["no_effect_false_name_rate"] == 0.25
    # one false name in 20 is 0.05 exactly, and meets the finer chain's bound of 0.05
    rows = [{"index": i, "kind": "none", "verdict": "none" if i else "bending",
             "correct": bool(i), "p_gap": 0.5, "simulations": 1, "baseline_error_u": {}}
            for i in range(20)]
    s = summarise(rows, 0.0)
    assert s["no_effect_false_name_rate"] == 0.05
    assert against_target("finer-chain", "no_effect_false_name_rate",
                          s["no_effect_false_name_rate"]) == "<= 0.05 met"


def test_out_of_library_counts_the_measurement_chain_as_a_name_flagged_or_not():
    # six out-of-library cases; the chain's hypothesis (its knobs beyond tolerance) is a
    # name like an effect: it counts as flagged when what it leaves is beyond the floor and
    # as a name without the flag when it is not
    verdicts = (("unexplained", None), ("measurement chain", True),
                ("measurement chain", False), ("bending", True), ("bending", False),
                ("none", None))
    rows = [{"index": i, "kind": "out_of_library", "verdict": v, "verdict_beyond_floor": f,
             "correct": v == "unexplained", "p_gap": 0.01, "simulations": 1,
             "baseline_error_u": {}} for i, (v, f) in enumerate(verdicts)]
    s = summarise(rows, 0.0)
    assert s["out_of_library_unexplained_or_flagged_rate"] == 3 / 6
    assert s["out_of_library_name_unflagged_rate"] == 2 / 6
    assert s["out_of_library_unexplained_rate"] == 1 / 6
    assert s["out_of_library_wrong_name_rate"] == 2 / 6      # sheet effects named


def test_the_measurement_chain_is_right_for_a_sensors_out_of_library_effect_only():
    # issue 46's figure: `unexplained`, flagged, or `measurement chain` for a sensor effect;
    # the chain unflagged for a load cell's drift counts, for a tool's lag it does not
    cases = (("load_cell_drift", "measurement chain"), ("tool_lag", "measurement chain"),
             ("camera_scale", "none"), ("adhesion", "unexplained"))
    rows = [{"index": i, "kind": "out_of_library", "truth": {n: [1.0]}, "verdict": v,
             "verdict_beyond_floor": False, "correct": v == "unexplained", "p_gap": 0.01,
             "simulations": 1, "baseline_error_u": {}} for i, (n, v) in enumerate(cases)]
    s = summarise(rows, 0.0)
    assert s["out_of_library_unexplained_or_flagged_rate"] == 1 / 4
    assert s["out_of_library_unexplained_flagged_or_chain_rate"] == 2 / 4
    assert s["out_of_library_per_effect"]["tool_lag"] == {"cases": 1,
                                                          "unexplained_or_flagged": 0}
    assert s["out_of_library_per_effect"]["adhesion"] == {"cases": 1,
                                                          "unexplained_or_flagged": 1}
