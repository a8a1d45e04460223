"""The default cell: config/cell.yaml is exactly CellParams() and explains its numbers."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from rheo_shaping.params.config import dump_cell, load_cell
from rheo_shaping.params.cell import CellParams
from rheo_shaping.params.schema import to_flat

CELL_YAML = Path(__file__).resolve().parents[2] / "config" / "cell.yaml"


def test_cell_yaml_loads_to_the_default_cell():
    assert load_cell(CELL_YAML) == CellParams()


def test_cell_yaml_holds_every_parameter_of_the_cell():
    data = yaml.safe_load(CELL_YAML.read_text())
    flat_file = {}

    def walk(tree, prefix=""):
        for k, v in tree.items():
            if isinstance(v, dict):
                walk(v, f"{prefix}{k}.")
            else:
                flat_file[f"{prefix}{k}"] = v
    walk(data["/**"]["ros__parameters"])
    assert set(flat_file) == set(to_flat(CellParams()))


def test_dump_of_the_default_cell_round_trips(tmp_path):
    f = tmp_path / "cell.yaml"
    f.write_text(dump_cell(CellParams()))
    assert load_cell(f) == CellParams()


def test_the_strip_is_the_papers_2g_spheres_split_in_four():
    """The strip weighs 2e-3 kg per 6.4 mm (paper Sec. 4.1's sphere on its 0.3125 kg/m strip);
    the default cell splits each paper sphere into four masses (docs/model.md, convergence)."""
    from rheo_shaping.sheet.simulation import build_chain
    p = CellParams()
    c, _ = build_chain(p)
    assert p.sheet.mass_per_length == pytest.approx(2e-3 / 6.4e-3, rel=1e-12)
    assert (p.sheet.n_masses + 1) % 4 == 0
    paper_spheres = (p.sheet.n_masses + 1) // 4
    # as many paper spheres as the 6.4 mm pitch fits on the sheet's rest length
    rest = c.rest_length.sum()
    assert paper_spheres == round(rest / 6.4e-3)
    # Sec. 4.1's lumping: mass per unit rest length x half of each adjacent link
    l = c.rest_length  # noqa: E741
    assert np.allclose(c.mass, p.sheet.mass_per_length * 0.5 *
                       (l[:-1] + l[1:]), rtol=1e-12, atol=0)
    # about a quarter of the paper's sphere each (the pitch is the sheet's length over N + 1)
    assert abs(c.mass.mean() - 0.5e-3) < 0.05 * 0.5e-3


def test_every_chosen_number_is_commented():
    """Every leaf line of the open geometry carries a comment (the why)."""
    open_keys = {"height", "fillet_radius", "n_masses", "top_bond_x", "bottom_bond_x",
                 "excess_length",
                 "mass_per_length", "shape", "width", "corner_radius", "home", "start_1", "end_1",
                 "start_2", "end_2", "start_3", "end_3", "start_4", "end_4", "d", "retract_speed"}
    lines = CELL_YAML.read_text().splitlines()
    seen = set()
    for i, line in enumerate(lines):
        key = line.strip().split(":", 1)[0]
        if key in open_keys and ":" in line:
            # the comment is on the line itself or on the lines just above it
            block = "\n".join(lines[max(0, i - 6):i + 1])
            assert "#" in block, f"config/cell.yaml: '{key}' has no comment"
            seen.add(key)
    assert open_keys <= seen
