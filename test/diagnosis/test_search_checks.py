"""The search checks what it finds (issue 46, point 3): a strong effect of each library kind,
at the top of its realistic range, in a world of another form (the dynamic world with a
soft mould, a soft tool pad and a hand-rolled sheet), diagnosed on two records with a third
held out: every effect whose linearised first fit, or whose first run, explains at least
CHECK_SHARE of the baseline's excess was simulated and refined to convergence before the
verdict; and the true effect is among those checked.  Against the model-form floor, such an
effect that leaves a clear gap (twice the floor's 95 % bound) is named, and by its own
name."""
from __future__ import annotations

import os
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.diagnosis.converge import CHECK_SHARE, share, strong
from rheo_shaping.diagnosis.engine import diagnose
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.sheet.effects import EFFECTS, EFFECT_NAMES
from rheo_shaping_validation.worlds.forms import FormParams
from rheo_shaping_validation.worlds.params import LayParams
from rheo_shaping_validation.worlds.sensors import world_record

#: long runs of the worlds' or the diagnosis's numerics: the core stage runs them, the
#: noble stage leaves them out (dev.py NOBLE_MARKS, docs/development.md)
pytestmark = pytest.mark.heavy

FORM = FormParams(mould_softness=300.0, tool_softness=100.0, thickness_variation=0.08,
                  thickness_seed=11)
LAY = LayParams(mode2=0.2, lift=5e-4, prestrain=-1e-3)


def top(name: str) -> tuple:
    """The effect at the top of its realistic range (power law: its lowest n)."""
    e = EFFECTS[name]
    if name == "power_law":
        return (min(lo for lo, _ in e.realistic),)
    vals = tuple(hi for _, hi in e.realistic)
    return vals if name != "tool_offset" else (vals[0], -vals[1])


def _records(name: str, value: tuple, n_masses: int, T: float) -> list:
    """Three records (movements 1, 3, 2) of the world of :data:`FORM` with effect ``name`` at
    ``value``, N ``n_masses``, ``T`` s."""
    p = CellParams()
    p = replace(p, sheet=replace(p.sheet, n_masses=n_masses),
                movement=replace(p.movement, process_time=T))
    truth = EFFECTS[name].apply(p, value)
    rng = np.random.default_rng(46)
    records = []
    for mv in (1, 3, 2):
        t_cell = replace(truth, movement=replace(truth.movement, number=mv))
        rec, _run = world_record(t_cell, movement_plan(t_cell), rng, lay=LAY, form=FORM,
                                 name=f"m{mv}")
        records.append(rec)
    return records


#: The kinds the suite checks (a diagnosis each, ~1.5 min on a busy 2-core machine): the tool
#: friction the search once refused and the power law the naming rule once refused; every
#: library kind with RHEO_FULL_SEARCH_CHECK=1 (13 min on the loaded machine, 8 of 8 passed).
KINDS = EFFECT_NAMES if os.environ.get("RHEO_FULL_SEARCH_CHECK") else ("friction_tool",
                                                                       "power_law")


@pytest.mark.parametrize("name", KINDS)
def test_every_strong_first_fit_is_checked_and_refined(name):
    records = _records(name, top(name), 15, 40.0)
    diag = diagnose(records[:2], records[2:], jobs=1, floor="numerics", initial_state="auto")
    if diag.verdict == "none":
        pytest.skip(f"{name}: no gap left by the baseline (J - 1 = {diag.J_base - 1:.3f})")
    for c in diag.effects:
        first = share(c.search.first_J, diag.J_base)
        if first >= CHECK_SHARE:
            assert c.checked, (name, c.names, first)
        if c.checked and strong(c, diag.J_base):
            assert c.search.converged, (name, c.names)
    true = next(c for c in diag.effects if c.names == (name,))
    assert true.checked or share(true.search.first_J, diag.J_base) < CHECK_SHARE, name


def strong_value(name: str) -> tuple:
    """The top of ``name``'s realistic range within the naming rule's prior (mass error: 25 %,
    not the benchmark's 40 %, which the prior charges by design); the tool offset held higher
    than written on both axes (pressed deeper into a soft cake, the model's rigid mould
    cannot follow it: docs/diagnosis.md, Limits)."""
    from rheo_shaping.diagnosis.naming import PRIOR
    if name == "tool_offset":
        return tuple(hi for _, hi in EFFECTS[name].realistic)
    if name == "mass_error":
        return PRIOR[name]
    return top(name)


#: The kinds named in the suite (~30 s each on a busy 2-core machine); every kind with
#: RHEO_FULL_SEARCH_CHECK=1.
NAMED = EFFECT_NAMES if os.environ.get("RHEO_FULL_SEARCH_CHECK") else ("friction_tool",
                                                                       "power_law",
                                                                       "tool_offset")


@pytest.mark.parametrize("name", NAMED)
def test_a_strong_effect_on_a_world_of_another_form_is_named_right(name):
    """N 31, 60 s records (the shipped floor's configuration), the form above: the verdict
    names the true effect alone wherever the baseline leaves at least twice the floor's 95 %
    bound (an effect that leaves less is within or near the floor: skipped, not failed).  On
    this form with the naming rule of the floor's level: friction_tool, power_law, the lifted
    tool offset, kelvin_c1, bending and thinning named; friction_mould (J - 1 0.17) and
    mass_error (0.19) within the floor."""
    records = _records(name, strong_value(name), 31, 60.0)
    diag = diagnose(records[:2], records[2:], jobs=1, floor="model-form",
                    initial_state="auto")
    q = diag.floor.q95_fit
    if not diag.J_base - 1.0 >= 2.0 * q:
        pytest.skip(f"{name}: the baseline leaves J - 1 = {diag.J_base - 1:.3f}, within twice "
                    f"the floor's bound {q:.3f}")
    assert diag.named == (name,), (name, diag.verdict, diag.floor.naming)
    n = diag.floor.naming
    assert n is not None and n.named
