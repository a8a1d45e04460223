"""``reproduce``'s figures, looked at (issue 28): a title on every figure, and the phase
labels of the history figures under the plot, covering neither curves nor a legend."""
from __future__ import annotations

import pytest

from _support.figures import legends, overlap, saved_figures, titles
from rheo_shaping.cli.reproduce import write_figures
from rheo_shaping.params.cell import CellParams
from rheo_shaping.study.reproduce import reproduce


@pytest.fixture(scope="module")
def figures(tmp_path_factory):
    study = reproduce(CellParams())
    out = tmp_path_factory.mktemp("figures")
    with saved_figures() as kept:
        files = write_figures(study, out)
    assert len(kept) == len(files) == 12
    return kept


def test_every_figure_has_a_title(figures):
    for fig, path in figures:
        main = fig._suptitle.get_text() if fig._suptitle is not None else fig.axes[0].get_title()
        assert main.strip(), f"{path}: no title"
        assert titles(fig), path


@pytest.mark.parametrize("name", ["movement1_history", "movement4_history",
                                  "half_speed_history"])
def test_phase_labels_cover_no_legend_and_no_plot(figures, name):
    fig, path = next((f, p) for f, p in figures if p.endswith(f"{name}.png"))
    legs = legends(fig)
    phase = [g for g in legs if "phases" in g.get_title().get_text()]
    assert len(phase) == 1, path
    (phase,) = phase
    for other in legs:
        if other is not phase:
            assert not overlap(phase, other), f"{path}: the phase labels cover a legend"
    for ax in fig.axes:
        assert not overlap(phase, ax.patch), f"{path}: the phase labels cover a plot"
    names = [t.get_text() for t in phase.get_texts()]
    assert names[:2] == ["approach", "forced deformation"], names
