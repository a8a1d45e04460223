"""The diagnosis report's figures, looked at (issue 28): a title on each, the profile
residual binned (no every-point speckle), a tool-force residual figure beside it, and
the effects chart saying why some candidates have no holdout bar."""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import pytest
from matplotlib.collections import PathCollection

from _support.figures import saved_figures
from rheo_shaping.diagnosis.engine import diagnose
from rheo_shaping.diagnosis.report import force_residual, write
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams
from rheo_shaping.sheet.effects import EFFECTS


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    p = CellParams()
    truth = EFFECTS["kelvin_c1"].apply(replace(p, movement=replace(p.movement,
                                                                   process_time=30.0)), (400.0,))
    recs = [replace(synthesize_record(truth, MeasurementParams(), seed=s, name=f"r{s}")[0],
                    scenario=replace(truth, effects=p.effects)) for s in (1, 2)]
    diag = diagnose(recs[:1], recs[1:], jobs=2, floor="numerics", initial_state="settled")
    out = tmp_path_factory.mktemp("report")
    with saved_figures() as kept:
        files = write(diag, out)
    return diag, {p.rsplit("/", 1)[-1]: f for f, p in kept}, files, out


def test_the_three_figures_are_written_and_named_in_the_report(report):
    diag, figs, files, out = report
    assert diag.verdict != "none" and diag.effects
    assert set(figs) == {"residual_map.png", "force_residual.png", "effects.png"}
    text = (out / "report.md").read_text()
    for name in figs:
        assert f"]({name})" in text


def test_each_figure_has_a_title(report):
    _, figs, _, _ = report
    assert "Profile residual" in figs["residual_map.png"]._suptitle.get_text()
    assert "Tool force residual" in figs["force_residual.png"]._suptitle.get_text()
    assert "Candidate effects" in figs["effects.png"].axes[0].get_title()


def test_no_panel_is_a_speckle_of_every_point(report):
    for name, fig in report[1].items():
        for ax in fig.axes:
            for c in ax.collections:
                if isinstance(c, PathCollection):
                    assert len(c.get_offsets()) < 500, f"{name}: {ax.get_title()}"


def test_the_force_figure_has_x_and_z_for_each_record(report):
    diag, figs, _, _ = report
    titles = [ax.get_title() for ax in figs["force_residual.png"].axes]
    assert titles == [f"{n}{h}: tool force {a}" for n, h in (("r1", ""), ("r2", " (holdout)"))
                      for a in "xz"]


def test_the_noise_band_is_the_load_cells_noise_in_the_axis_units(report):
    diag, figs, _, _ = report
    sf_mN = diag.noise.force_N * 1e3
    for ax in figs["force_residual.png"].axes:
        (band,) = [p for p in ax.patches if "noise" in p.get_label()]
        ys = band.get_path().transformed(band.get_patch_transform()).vertices[:, 1] \
            if hasattr(band, "get_patch_transform") else band.get_xy()[:, 1]
        assert min(ys) == pytest.approx(-sf_mN) and max(ys) == pytest.approx(sf_mN)


def test_effects_chart_says_why_a_candidate_has_no_holdout_bar(report):
    diag, figs, _, _ = report
    ax = figs["effects.png"].axes[0]
    assert "simulation on the holdout records" in ax.get_title()
    notes = [t.get_text() for t in ax.texts]
    unchecked = [e for e in diag.effects if not e.checked]
    assert unchecked and sum("holdout: not simulated" in n for n in notes) >= len(unchecked)


def test_no_tool_force_no_force_figure(tmp_path):
    rec = SimpleNamespace(has_wrench=False, name="r")
    diag = SimpleNamespace(residual_maps=[(SimpleNamespace(record=rec), None, None, None)])
    assert force_residual(diag, tmp_path / "f.png") is False
    assert not (tmp_path / "f.png").exists()
