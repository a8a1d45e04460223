"""Property-based tests of the sheet core: random valid cells and tool paths.

Whatever the cell, a run must never produce NaN, never let a sphere into an
obstacle beyond the 1e-5 m tolerance, and never shorten a link's plastic
elongation while it is under tension.  Invalid inputs must give a clear error.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from rheo_shaping.params.cell import CellParams
from rheo_shaping.params.schema import ParameterError
from rheo_shaping.sheet.paths import PolylinePath
from rheo_shaping.sheet.simulation import run_scenario
from rheo_shaping.sheet.tools import tool_shape

PENETRATION_TOL_M = 1e-5


@st.composite
def cells(draw):
    """A random valid cell and a tool path that keeps clear of the cake by a sheet thickness."""
    p = CellParams()
    thickness = draw(st.floats(2e-3, 6e-3))
    height = draw(st.floats(0.04, 0.12))
    fillet = draw(st.floats(0.002, 0.02))
    material = replace(p.material, k1=draw(st.floats(40.0, 250.0)),
                       c1=draw(st.sampled_from([0.0, 0.0, 150.0])),
                       c2=draw(st.floats(400.0, 4000.0)))
    sheet = replace(p.sheet, thickness=thickness, n_masses=draw(st.integers(4, 40)),
                    top_bond_x=-fillet - draw(st.floats(0.005, 0.04)),
                    bottom_bond_x=draw(st.floats(thickness + 1e-3, 0.06)),
                    excess_length=draw(st.sampled_from([0.0, 0.0, 0.004])))
    cake = replace(p.cake, height=height, fillet_radius=fillet)
    kind = draw(st.sampled_from(["circle", "rounded_rectangle", "polygon"]))
    tool = replace(p.tool, shape=kind, radius=draw(st.floats(0.004, 0.015)),
                   width=draw(st.floats(0.008, 0.03)), height=draw(st.floats(0.01, 0.05)),
                   corner_radius=draw(st.floats(0.0, 0.004)),
                   vertices=(0.0, -0.01, 0.012, 0.0, 0.0, 0.01))
    speed = draw(st.floats(5e-4, 5e-3))
    movement = replace(p.movement, speed=speed, process_time=30.0)
    solver = replace(p.solver, settle_time=0.2)
    cell = replace(p, material=material, sheet=sheet, cake=cake, tool=tool, movement=movement,
                   solver=solver)
    # tool path: from outside toward the sheet, ending where the tool face keeps a
    # thickness (plus 0.1 mm) from the wall and the workplane
    shape = tool_shape(tool)
    outline = shape.outline(256)
    left, bottom = -outline[:, 0].min(), -outline[:, 1].min()
    z_end = draw(st.floats(bottom + thickness + 1e-4, height))
    x_end = left + thickness + 1e-4 + draw(st.floats(0.0, 0.02))
    start = np.array([x_end + draw(st.floats(0.02, 0.05)), z_end + draw(st.floats(0.0, 0.04))])
    end = np.array([x_end, z_end])
    travel = float(np.hypot(*(end - start)))
    t1 = travel / speed
    times = np.array([0.0, t1, t1 + 5.0, t1 + 5.0 + travel / speed])
    path = PolylinePath(times, np.array([start, end, end, start]))
    return cell, path


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(cells())
def test_random_cells_stay_finite_unpenetrated_and_flow_forward(case):
    cell, path = case
    res = run_scenario(cell, path, t_end=min(30.0, path.duration + 2.0))
    assert np.all(np.isfinite(res.x)) and np.all(np.isfinite(res.tension))
    assert np.all(res.tension >= 0.0)
    # penalty contacts: penetration = force / K_c
    kc = cell.solver.contact_stiffness
    worst_mould = np.max(np.hypot(*np.moveaxis(res.mould_force, -1, 0))) / kc
    worst_tool = np.max(np.hypot(*np.moveaxis(res.tool_contact, -1, 0))) / kc
    assert max(worst_mould, worst_tool) <= PENETRATION_TOL_M
    # plastic elongation never decreases while a link is under tension
    dp = np.diff(res.plastic, axis=0)
    taut = res.tension[1:] > 0.0
    assert np.all(dp[taut] >= -1e-15)


@pytest.mark.parametrize("name, value", [
    ("material.k1", -1.0), ("material.k1", 0.0), ("material.c2", float("nan")),
    ("material.c1", -5.0), ("sheet.n_masses", 0), ("sheet.mass_per_length", 0.0),
    ("sheet.thickness", -1e-3), ("cake.height", float("inf")), ("solver.dt", 0.0),
    ("solver.dt_settle", -1e-3), ("movement.speed", float("nan")), ("tool.shape", "hexagon"),
])
def test_invalid_cell_values_are_refused_with_the_parameter_named(name, value):
    from rheo_shaping.params.schema import from_flat
    with pytest.raises(ParameterError) as err:
        from_flat(CellParams, {name: value})
    assert f"'{name}'" in str(err.value) and "expected" in str(err.value)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["material.k1", "material.c2", "sheet.mass_per_length", "cake.height",
                        "solver.dt", "movement.speed", "sheet.thickness"]),
       st.one_of(st.floats(max_value=0.0), st.just(float("nan")), st.just(float("inf")),
                 st.text(max_size=3), st.booleans()))
def test_random_invalid_values_always_give_a_clear_error(name, value):
    from rheo_shaping.params.schema import from_flat
    # c2 = inf: no plastic flow, valid
    assume(not (name == "material.c2" and value == float("inf")))
    with pytest.raises(ParameterError) as err:
        from_flat(CellParams, {name: value})
    assert f"'{name}'" in str(err.value)
