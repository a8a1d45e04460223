"""The core's params-file rule without ROS (rcl's rule, checked against rcl in
test/nodes/test_params_files.py): what it refuses, with file, key, value and what was expected."""
from __future__ import annotations

import pytest

from rheo_shaping.params.config import ConfigError, check_params_file, load_cell, node_of
from rheo_shaping.params.cell import CellParams


@pytest.mark.parametrize("text, fragments", [
    ("material:\n  k1: 95.0\n", ["section 'material' has no 'ros__parameters'", "'k1' = 95.0"]),
    ("/**:\n  ros__parameters:\n    tool: {home: [0.03, 1]}\n",
     ["'tool.home' = [0.03, 1]", "one type", "a float and an integer"]),
    ("/**/simulator:\n  ros__parameters:\n    sheet: {n_masses: 31}\n",
     ["section '/**/simulator'", "'sheet.n_masses' = 31", "'/**' section"]),
    ("/**/planner:\n  ros__parameters:\n    control_rate: 0.1\n",
     ["'control_rate' = 0.1", "[1, 1000] Hz", "section '/**/planner'"]),
    ("/**:\n  ros__parameters:\n    a: 1\n  other: 2\n", ["'other' beside 'ros__parameters'"]),
])
def test_refused_with_a_clear_message(tmp_path, text, fragments):
    path = tmp_path / "p.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_cell(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_node_sections_and_namespaces(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("/**:\n  ros__parameters:\n    movement: {number: 2}\n"
                    "cell2:\n  planner:\n    ros__parameters:\n      control_rate: 20.0\n"
                    "/**/monitor:\n  ros__parameters:\n    use_sim_time: true\n")
    found = check_params_file(path)
    assert set(found) == {"/**", "cell2/planner", "/**/monitor"}
    assert [node_of(n) for n in sorted(found)] == [None, "monitor", "planner"]
    assert load_cell(path).movement.number == 2
    assert load_cell(path) != CellParams()


def test_a_params_file_is_read_once_to_load_its_cell(monkeypatch):
    """load_cell reads the YAML once and checks that same text (it read the file twice)."""
    from pathlib import Path

    from rheo_shaping.params import config
    reads: list[str] = []
    real = config.read_yaml

    def counting(path):
        reads.append(str(path))
        return real(path)

    monkeypatch.setattr(config, "read_yaml", counting)
    cell_file = Path(__file__).resolve().parents[2] / "config" / "cell.yaml"
    cell = config.load_cell(cell_file)
    assert reads == [str(cell_file)]
    assert cell.movement.number >= 1
