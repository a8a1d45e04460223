"""The monitor's abort threshold (rheo_shaping.safety.abort_budget.monitor_abort_ratio):
a configured abort_ratio as given, else safety principle 4 at the configured speed."""
from __future__ import annotations

from dataclasses import replace

import pytest

from rheo_shaping.params.cell import CellParams
from rheo_shaping.params.schema import ParameterError
from rheo_shaping.safety.abort_budget import (abort_horizon, configured_speed_threshold,
                                              monitor_abort_ratio)


def test_a_configured_abort_ratio_is_taken_as_given():
    choice = monitor_abort_ratio(CellParams(), 0.85, 1.0, 0.005)
    assert choice.ratio == 0.85 and choice.budget is None and choice.note == ""


def test_a_configured_ratio_beyond_principle_4_is_refused_with_the_bound():
    """abort_ratio 1.0 sat inside the schema and tore the sheet: a set ratio above the bound
    principle 4 gives at the configured speed is refused, naming both; the bound itself is
    taken."""
    cell = CellParams()
    h = abort_horizon(cell, 0.1, 0.0)
    F_abort, r, _ = configured_speed_threshold(cell, h, 0.005)
    bound = F_abort / cell.material.F_break
    assert monitor_abort_ratio(cell, bound, h, 0.005).ratio == bound
    with pytest.raises(ParameterError, match=rf"^parameter 'abort_ratio' = 1 is invalid: "
                                             rf"expected at most {bound:.4f}"):
        monitor_abort_ratio(cell, 1.0, h, 0.005)
    with pytest.raises(ParameterError, match="abort_ratio"):
        monitor_abort_ratio(cell, bound * (1 + 1e-9), h, 0.005)


def test_ratio_zero_is_principle_4_at_the_configured_speed():
    cell = CellParams()
    h = abort_horizon(cell, 0.1, 0.0)
    F_abort, r, _ = configured_speed_threshold(cell, h, 0.005)
    choice = monitor_abort_ratio(cell, 0.0, h, 0.005)
    Fb = cell.material.F_break
    # F_abort = F_break - r (t_detect + t_stop) - 3 sigma
    assert choice.ratio * Fb == pytest.approx(Fb - r * h - 3 * 0.005, rel=1e-12)
    assert choice.ratio == pytest.approx(F_abort / Fb, rel=1e-12)
    assert 0 < choice.ratio < 1 and choice.budget["r"] == r
    assert f"{F_abort:.4f} N" in choice.note


def test_no_threshold_at_a_speed_beyond_the_principle_is_refused_by_name():
    cell = CellParams()
    fast = replace(cell, movement=replace(cell.movement, speed=0.02))
    with pytest.raises(ParameterError, match=r"^abort_ratio 0: no threshold meets safety "
                                             r"principle 4 at movement.speed 0.02 m/s"):
        monitor_abort_ratio(fast, 0.0, 30.0, 0.005)
