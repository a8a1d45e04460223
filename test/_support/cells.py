"""The cells the tests run, and params files for them (ROS-free)."""
from __future__ import annotations

from pathlib import Path

import yaml

from rheo_shaping.params.config import dump_cell, load_cell
from rheo_shaping.params.cell import CellParams

REPO = Path(__file__).resolve().parents[2]


def base_cell() -> CellParams:
    """config/cell.yaml's cell when it exists, else the default cell."""
    path = REPO / "config" / "cell.yaml"
    return load_cell(path) if path.exists() else CellParams()


def write_params(path: Path, cell: CellParams, simulator=None, planner=None,
                 monitor=None) -> Path:
    """A params file of ``cell`` with optional node sections (dicts of settings)."""
    data = yaml.safe_load(dump_cell(cell))
    for name, section in (("simulator", simulator), ("planner", planner), ("monitor", monitor)):
        if section:
            data[name] = {"ros__parameters": section}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path
