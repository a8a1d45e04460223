"""One cell for every node (rheo_shaping.params.fingerprint), without ROS."""
from __future__ import annotations

import json
from dataclasses import replace

from rheo_shaping.params.fingerprint import cell_fingerprint, cell_message, cell_mismatch
from rheo_shaping.params.cell import CellParams


def test_equal_cells_agree_and_the_message_carries_every_parameter():
    a, b = CellParams(), CellParams()
    assert cell_fingerprint(a) == cell_fingerprint(b) and len(cell_fingerprint(a)) == 16
    assert cell_mismatch(a, cell_message(b)) == ""
    values = json.loads(cell_message(a))["values"]
    assert values["movement.speed"] == a.movement.speed
    assert values["material.F_break"] == a.material.F_break and len(values) > 40


def test_a_slip_in_one_parameter_is_named_with_both_values():
    ours = CellParams()
    slip = replace(ours, movement=replace(ours.movement, speed=0.005, number=3))
    assert cell_fingerprint(slip) != cell_fingerprint(ours)
    why = cell_mismatch(slip, cell_message(ours), "the planner", "the simulator")
    assert why.startswith("the cell differs from the simulator's: ")
    assert "movement.number = 3 (the planner) vs 4 (the simulator)" in why
    assert "movement.speed = 0.005 (the planner) vs 0.001 (the simulator)" in why


def test_a_message_that_is_no_cell_is_a_mismatch():
    assert "is not a cell fingerprint" in cell_mismatch(CellParams(), "hello")
    assert "is not a cell fingerprint" in cell_mismatch(CellParams(), '{"fingerprint": 3}')
