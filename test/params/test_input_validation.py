"""Core input validation: bad masses, lengths, stiffnesses, dashpots and time
steps raise ValueError naming the quantity (issue 7), never NaN results."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.material.three_element import ThreeElement, elongation_step, step_coefficients
from rheo_shaping.params.cell import CellParams
from rheo_shaping.sheet.simulation import Simulation, build_chain

BAD_POSITIVE = [math.nan, 0.0, -1.0, -math.inf]


@pytest.fixture(scope="module")
def chain():
    params = replace(CellParams(), sheet=replace(CellParams().sheet, n_masses=5))
    return build_chain(params)[0]


@pytest.mark.parametrize("field,unit", [("mass", "kg"), ("rest_length", "m"), ("k1", "N/m")])
@pytest.mark.parametrize("bad", BAD_POSITIVE)
def test_chain_rejects_non_positive_quantities(chain, field, unit, bad):
    values = np.array(getattr(chain, field), dtype=float)
    values[2] = bad
    with pytest.raises(ValueError, match=rf"^{field}\[2\] = .* {unit} is invalid"):
        replace(chain, **{field: values})


@pytest.mark.parametrize("field", ["c1", "c2"])
@pytest.mark.parametrize("bad", [math.nan, -1.0])
def test_chain_rejects_negative_or_nan_dashpots(chain, field, bad):
    values = np.array(getattr(chain, field), dtype=float)
    values[0] = bad
    with pytest.raises(ValueError, match=rf"^{field}\[0\] = .* N s/m is invalid"):
        replace(chain, **{field: values})


def test_chain_accepts_rigid_c2_and_zero_c1(chain):
    """No plastic flow (c2 = inf: the link is a Kelvin-Voigt element) and no damper beside
    the spring (c1 = 0) are limits the model takes; they are kept as given."""
    rigid = replace(chain, c2=np.full_like(chain.c2, math.inf), c1=np.zeros_like(chain.c1))
    assert np.all(np.isinf(rigid.c2)) and np.all(rigid.c1 == 0.0)
    assert np.array_equal(rigid.k1, chain.k1)
    assert np.array_equal(rigid.rest_length, chain.rest_length)


def test_chain_rejects_a_zero_c2(chain):
    with pytest.raises(ValueError, match=r"^c2\[0\] = 0.0 N s/m is invalid"):
        replace(chain, c2=np.zeros_like(chain.c2))


def test_chain_rejects_mismatched_sizes_and_bad_radius(chain):
    with pytest.raises(ValueError, match="rest_length must have 6 values"):
        replace(chain, rest_length=chain.rest_length[:-1])
    for bad in BAD_POSITIVE:
        with pytest.raises(ValueError, match=r"^radius = .* m is invalid"):
            replace(chain, radius=bad)
    with pytest.raises(ValueError, match=r"^gravity = .* is invalid"):
        replace(chain, gravity=math.nan)
    with pytest.raises(ValueError, match="anchor_top must be a finite point"):
        replace(chain, anchor_top=np.array([math.nan, 0.0]))


@pytest.mark.parametrize("dt", [0.0, -0.1, math.nan, math.inf])
def test_time_steps_are_checked_everywhere(dt):
    sim = Simulation(replace(CellParams(), sheet=replace(CellParams().sheet, n_masses=5)))
    with pytest.raises(ValueError, match=r"dt = .* is invalid"):
        sim.model.step(sim.state, dt, sim.state.tool)
    with pytest.raises(ValueError, match="dt"):
        step_coefficients(95.0, 0.0, 1300.0, 0.0, dt)
    with pytest.raises(ValueError, match="dt"):
        elongation_step(95.0, 0.0, 1300.0, 0.0, 0.0, 1e-3, dt)


@pytest.mark.parametrize("name", ["k1", "c1", "c2"])
def test_material_rejects_nan_and_negative(name):
    for bad in (math.nan, -5.0):
        with pytest.raises(ValueError, match=name):
            ThreeElement(**{"k1": 95.0, "c1": 0.0, "c2": 1300.0, name: bad})


@pytest.mark.parametrize("text,message", [
    ("/**:\n  ros__parameters:\n    material: {k1: [1, 2}\n", r"bad\.yaml: line 3, column \d+"),
    ("/**:\n  ros__parameters:\n    material: {k1: fast}\n",
     r"parameter 'material.k1' = 'fast' is invalid: expected a number in \(0, 1e\+06\] N/m"),
    ("/**:\n  ros__parameters:\n    sheet: {thicknes: 0.004}\n",
     r"unknown parameter 'sheet.thicknes'"),
    ("/**:\n  ros__parameters:\n    effects: {mass_error: -2.0}\n",
     r"parameter 'effects.mass_error' = -2.0 is invalid: expected a value in \[-0.9, 10\]"),
])
def test_malformed_params_file_is_one_line_and_writes_nothing(tmp_path, capsys, text, message):
    """A params file's mistakes: one line naming file / parameter, value and range; no plot
    written."""
    import re

    from rheo_shaping.cli import main
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    plot = tmp_path / "plot.png"
    assert main(["simulate", "--params", str(bad), "--plot", str(plot)]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not plot.exists()


@pytest.mark.parametrize("section, name, value, why", [
    ("solver", "dt_still", 5e-324, "movement.process_time would take inf steps"),
    ("solver", "max_tool_step", 1e-12, "would take 1.2e+11 steps"),
    ("solver", "dt_settle", 1e-9, "settle_time would take 1e+09 steps"),
    ("sheet", "thickness", 5e-324, "whose half (the masses' contact radius) is > 0 m"),
])
def test_values_inside_their_range_that_no_run_could_finish_are_refused(section, name, value,
                                                                        why):
    """benchmarks/fuzz_bounds.py: a step of 5e-324 s lies inside (0, 100] s but a run
    would never end; a sheet 5e-324 m thick has masses of radius 0 m."""
    from dataclasses import replace as _replace

    from rheo_shaping.params.cell import CellParams
    from rheo_shaping.params.schema import ParameterError
    cell = CellParams()
    with pytest.raises(ParameterError, match=f"parameter '{section}.{name}'") as exc:
        _replace(cell, **{section: _replace(getattr(cell, section), **{name: value})})
    assert why in str(exc.value)
