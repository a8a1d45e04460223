"""The benchmark's worlds by name: each implements the one World protocol (mypy holds the
protocol, test/architecture/test_types.py), and a case asks its world to run and measure
instead of testing which one it is."""
from __future__ import annotations

import inspect
import random

from rheo_shaping.diagnosis import DEFAULTS, FloorKind, InitialMode
from rheo_shaping_validation.benchmark import cases
from rheo_shaping_validation.benchmark.world import (WORLDS, DynamicWorld, FinerChain, World,
                                                     true_numerics)
from rheo_shaping_validation.benchmark.cases import base_cell
from rheo_shaping_validation.worlds.params import WorldEffects, WorldNumerics

MEMBERS = ("for_case", "drawn", "true_cell", "run", "measure", "true_n_masses", "describe")


def test_each_world_is_named_and_has_every_member_of_the_protocol():
    assert list(WORLDS) == ["finer-chain", "dynamic"]
    for name, world in WORLDS.items():
        assert world.name == name
        for member in MEMBERS:
            assert callable(getattr(world, member)), (name, member)
            assert hasattr(World, member)


def test_what_each_world_draws_and_runs():
    cell = base_cell(31, 20.0)
    fine = FinerChain.for_case(1, 0)
    assert fine.drawn(random.Random(1), WorldEffects()) is fine        # draws nothing
    assert fine.true_cell(cell) == true_numerics(cell) and fine.true_n_masses(31) == 63
    assert fine.options.floor is FloorKind.NUMERICS
    assert fine.options.initial_state is InitialMode.SETTLED
    dyn = DynamicWorld.for_case(1, 0)
    rng = random.Random(1)
    drawn = dyn.drawn(rng, WorldEffects())
    assert drawn.lay != dyn.lay and drawn.true_cell(cell) == cell     # its laying, drawn
    assert dyn.true_n_masses(31) == WorldNumerics().n_masses and dyn.options == DEFAULTS
    assert drawn.describe()["lay"] == vars(drawn.lay)


def test_a_case_names_its_world_and_never_asks_which_one_it_is():
    src = inspect.getsource(cases.make_case)
    assert "WORLDS[" in src
    assert "lay is not None" not in src and '"dynamic"' not in src
