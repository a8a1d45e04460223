"""What the diagnosis does to spend less time, shown to change nothing it computes (no ROS):
a record's step schedule kept between runs gives the same run to the last bit, and the
stages' linear algebra on one BLAS thread gives the thread count back."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from rheo_shaping.diagnosis.blas import _blas_thread_calls, blas_single_thread
from rheo_shaping.params.cell import CellParams
from rheo_shaping.sheet import simulation
from rheo_shaping.sheet.paths import PolylinePath


def _path() -> PolylinePath:
    """A tool path down onto the sheet and back (times [s], points [m])."""
    p = CellParams()
    home = np.asarray(p.tool.home, float)
    return PolylinePath(np.array([0.0, 4.0, 8.0]),
                        np.array([home, home + [0.0, -0.01], home]))


def test_a_kept_schedule_gives_the_same_run():
    p = CellParams()
    p = replace(p, sheet=replace(p.sheet, n_masses=15))
    simulation._SCHEDULES.clear()
    first = simulation.run_scenario(p, _path(), t_end=8.0)
    assert len(simulation._SCHEDULES) == 1          # planned once, kept
    again = simulation.run_scenario(p, _path(), t_end=8.0)
    for name in ("t", "x", "tension", "tool", "tool_force"):
        assert np.array_equal(getattr(first, name), getattr(again, name)), name
    simulation._SCHEDULES.clear()
    fresh = simulation.run_scenario(p, _path(), t_end=8.0)
    assert np.array_equal(fresh.x, first.x)


def test_blas_single_thread_restores_the_thread_count():
    calls = _blas_thread_calls()
    before = [get() for _set, get in calls]
    with blas_single_thread():
        assert all(get() == 1 for _set, get in calls)
    assert [get() for _set, get in calls] == before
