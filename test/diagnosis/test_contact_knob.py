"""The baseline's contact knob: the mould's and the tool's stiffness on a log scale, the
diagnosis starting three decades softer than the written (rigid) penalty at u = 0 and going
softer only, to six decades at u = 1 (a cake is a sponge); and what a softer contact does
to the sheet (each resting mass sinks by F / K_c, exactly)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.diagnosis.baseline import (CHAIN, KNOBS, SHEET, SYMMETRIC, reference, sheet_box,
                                             values, with_sheet)
from rheo_shaping.params.cell import CellParams
from rheo_shaping.sheet.paths import PolylinePath
from rheo_shaping.sheet.simulation import run_scenario

NAME = "solver.contact_stiffness"


def test_the_knob_is_logarithmic_and_starts_three_decades_softer_than_written():
    cell = CellParams()
    kc = cell.solver.contact_stiffness
    for u, expected in ((-1.0, kc), (0.0, kc * 1e-3), (0.5, kc * 10 ** -4.5), (1.0, kc * 1e-6)):
        moved = with_sheet(cell, {NAME: u})
        assert moved.solver.contact_stiffness == pytest.approx(expected, rel=1e-12)
        assert values(cell, {NAME: u})[NAME] == pytest.approx(expected, rel=1e-12)
    start = reference(cell)                      # where the diagnosis starts: u = 0 of all
    assert start.solver.contact_stiffness == pytest.approx(kc * 1e-3, rel=1e-12)
    assert start == with_sheet(cell, {k.name: 0.0 for k in SHEET})
    lo, hi = sheet_box()                         # from the start, only softer
    j = [k.name for k in SHEET].index(NAME)
    assert (lo[j], hi[j]) == (0.0, 1.0)
    assert np.all(np.delete(lo, j) == -1.0) and np.all(np.delete(hi, j) == 1.0)
    assert np.all(np.c_[sheet_box(0.0)] == 0.0)                 # held
    # a benchmark draws its truths within the two-sided knobs only (the contact stays rigid)
    assert KNOBS[NAME] not in SYMMETRIC and len(SYMMETRIC) == len(SHEET) - 1


def test_a_softer_contact_sinks_each_resting_mass_by_its_force_over_the_stiffness():
    """The penalty contact's closed form: a mass resting on a flat face (the cake's top, the
    workplane) sits F / K_c below where it touches; three decades softer (the knob at u 0,
    where the diagnosis starts) it sinks by F_soft / K_soft - F_rigid / K_rigid."""
    base = CellParams()
    base = replace(base, solver=replace(base.solver, settle_time=0.5),
                   sheet=replace(base.sheet, n_masses=20))
    far = np.array([0.3, 0.3])                     # the tool stands far off the sheet
    path = PolylinePath(np.array([0.0, 1.0]), np.array([far, far]))
    rigid = run_scenario(base, path, t_end=1.0)
    soft_cell = with_sheet(base, {NAME: 0.0})
    soft = run_scenario(soft_cell, path, t_end=1.0)
    k_r, k_s = base.solver.contact_stiffness, soft_cell.solver.contact_stiffness
    f_r, f_s = rigid.mould_force[-1], soft.mould_force[-1]
    flat = (f_s[:, 1] > 1e-3) & (f_s[:, 0] == 0.0) & (f_r[:, 0] == 0.0)
    assert flat.sum() >= 3                         # on the cake's top and the workplane
    sink = rigid.x[-1, flat, 1] - soft.x[-1, flat, 1]
    np.testing.assert_allclose(sink, f_s[flat, 1] / k_s - f_r[flat, 1] / k_r, rtol=2e-3)
    assert np.all(sink > 0.0) and sink.max() > 4e-6     # a thousand times softer: microns


def test_a_sheet_held_as_written_keeps_the_written_contact():
    """``--baseline held`` (the sheet knobs' box times 0, the gap watch's default on rigid
    sheet-model records): the diagnosis runs the cell exactly as written, the contact at its
    written stiffness, not three decades softer; the table reports the written value."""
    from types import SimpleNamespace

    from rheo_shaping.diagnosis.context import FitContext
    from rheo_shaping.diagnosis.result import baseline_table

    cell = CellParams()
    kc = cell.solver.contact_stiffness
    assert reference(cell, 0.0) == cell
    record = SimpleNamespace(record=SimpleNamespace(scenario=cell))
    u0 = np.zeros(len(SHEET))
    held = FitContext([], [], None, None, None, 1e-4, 1e-3, 0.0)   # type: ignore[arg-type]
    fitted = replace(held, sheet_lim=1.0)
    assert held.params(record, u0) == cell                          # type: ignore[arg-type]
    assert fitted.params(record, u0).solver.contact_stiffness == pytest.approx(kc * 1e-3)
    n_all = len(SHEET) + len(CHAIN)
    table = baseline_table(cell, np.zeros(n_all), 0.0)
    assert table[NAME]["value"] == kc and table[NAME]["written"] == kc
    assert baseline_table(cell, np.zeros(n_all))[NAME]["value"] == pytest.approx(kc * 1e-3)
