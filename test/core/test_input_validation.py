"""Core input validation: bad masses, lengths, stiffnesses, dashpots and time
steps raise ValueError naming the quantity (issue 7), never NaN results."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.material import ThreeElement, elongation_step, step_coefficients
from rheo_shaping.params import CellParams
from rheo_shaping.simulation import Simulation, build_chain

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
    replace(chain, c2=np.full_like(chain.c2, math.inf), c1=np.zeros_like(chain.c1))


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
