"""The core behind the nodes' settings (no ROS): the choice of d (paper Fig. 18), params
files with node sections, and docs/ros.md's tables."""
from __future__ import annotations

from dataclasses import replace

import pytest

from rheo_shaping.params.config import load_cell
from rheo_shaping.params.node_params import NODE_PARAMS, parameter_table
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.choose_d import best_d, d_values

from _support.cells import REPO, base_cell


def test_best_d_is_the_smallest_F_max_within_the_delta_limit():
    cell = base_cell()
    ds = d_values(0.012, 0.017, 0.0025)
    assert ds.tolist() == pytest.approx([0.012, 0.0145, 0.017])
    choice = best_d(cell, ds, delta_limit=1.0)
    assert choice.F_max == min(r.F_max for r in choice.runs)
    assert choice.d in ds
    limit = sorted(r.delta for r in choice.runs)[1]        # admits the two smallest-Delta runs
    strict = best_d(cell, ds, delta_limit=limit)
    assert strict.delta <= limit
    with pytest.raises(ValueError, match="keeps Delta"):
        best_d(cell, ds, delta_limit=1e-9)


def test_load_cell_reads_the_wildcard_section_and_node_sections_hold_node_settings(tmp_path):
    ros = tmp_path / "ros.yaml"
    ros.write_text("/**:\n  ros__parameters:\n    material: {k1: 90.0}\n"
                   "/**/simulator:\n  ros__parameters:\n    real_time_factor: 20.0\n"
                   "planner:\n  ros__parameters:\n    control_rate: 100.0\n"
                   "/cell2/monitor:\n  ros__parameters:\n    abort_ratio: 0.5\n")
    want = replace(CellParams(), material=replace(CellParams().material, k1=90.0))
    for node in ("simulator", "planner", "monitor"):
        assert load_cell(ros, node) == want
    assert load_cell(ros) == want


#: Shipped YAML files that are not a cell's params file (diagnostic_aggregator's analyzers).
NOT_CELLS = {"diagnostics_aggregator.yaml"}


def test_shipped_params_files_load_in_the_core_and_their_node_sections_are_valid():
    from rheo_shaping.params.config import read_yaml, flatten
    from rheo_shaping.params.node_params import ROS_BUILTIN_PARAMETERS
    from rheo_shaping.params.schema import from_flat
    cells = [p for p in sorted((REPO / "config").glob("*.yaml")) if p.name not in NOT_CELLS]
    assert cells
    for path in cells:
        load_cell(path)
        data = read_yaml(path)
        for node, cls in NODE_PARAMS.items():
            section = data.get(f"/**/{node}", {}).get("ros__parameters", {})
            assert section, f"{path.name}: no '/**/{node}' section"
            flat = {k: v for k, v in flatten(section).items() if k not in ROS_BUILTIN_PARAMETERS
                    and k.split(".", 1)[0] not in ("material", "sheet", "cake", "tool", "movement",
                                                   "solver")}
            from_flat(cls, flat, where=f"{path.name}: {node}")


def test_docs_parameter_tables_are_current():
    doc = (REPO / "docs" / "ros.md").read_text()
    for name, cls in NODE_PARAMS.items():
        assert parameter_table(cls) in doc, f"docs/ros.md: regenerate the `{name}` table " \
                                           f"(python -m rheo_shaping.params.node_params)"


def test_the_gap_watch_diagnoses_with_the_diagnosis_baseline_modes():
    """``gap_watch``'s ``diagnosis_baseline`` takes exactly ``diagnose --baseline``'s modes
    (the schema keeps its own literal: params imports no diagnosis)."""
    from dataclasses import fields
    from rheo_shaping.diagnosis.baseline import BASELINE_MODES
    from rheo_shaping.params.gapwatch_params import GapWatchNodeParams
    spec = next(f for f in fields(GapWatchNodeParams)
                if f.name == "diagnosis_baseline").metadata["spec"]
    assert sorted(spec.choices) == sorted(BASELINE_MODES)
    assert GapWatchNodeParams().diagnosis_baseline in BASELINE_MODES
