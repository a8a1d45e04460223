"""Residual plots of an identification (matplotlib, Agg canvas, no pyplot state).

They are what validates the material model: a model that fits leaves
residuals without structure, a wrong one leaves a trend (a Maxwell fit of a
Burgers material, for instance, shows a systematic wave at the start of the
pull).
"""
from __future__ import annotations

import os
import textwrap
from typing import Callable, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..material.closed_forms import tensile_force
from .paper_method import PaperIdentification, eq13_points
from .joint_fit import model_tensile_force
from ..material.three_element import SPECIMEN_LENGTH_M, ThreeElement
from .material_data import TensileCurve
from .model_choice import JointIdentification

_COLOURS = {"maxwell": "tab:blue", "three-element": "tab:orange", "burgers": "tab:green"}


def _discarded(ax, tensile: Sequence[TensileCurve], offsets: Sequence[float | None],
               keeps: Sequence[int]) -> None:
    for c, off, keep in zip(tensile, offsets, keeps):
        ax.plot(c.t[keep:], c.force[keep:] - (off or 0.0), ".", ms=1.5, color="0.75")


def _save(fig: Figure, path: str | os.PathLike) -> None:
    FigureCanvasAgg(fig)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _joint_tensile(ax, result: JointIdentification, tensile: Sequence[TensileCurve]) -> None:
    fits, data = result.fits, result.data
    ax.set_title("tensile curves (fitted offset removed; grey: after crack) and fits; chosen: "
                 f"{result.model}")
    offs = ([o.value for o in fits[result.model].offsets] if result.model is not None
            else [c.offset or 0.0 for c in data.curves])
    if tensile:
        _discarded(ax, list(tensile), offs, [c.crack.keep for c in data.curves])
    for i, c in enumerate(data.curves):
        ax.plot(c.t, c.force - offs[i], ".", ms=2, color="k",
                label="data (kept)" if i == 0 else None)
        if c.crack.t_crack is not None:           # found
            ax.axvline(c.crack.t_crack, color="r", lw=0.5, ls=":")
    for m, f in fits.items():
        for i, c in enumerate(data.curves):
            tt = np.linspace(min(c.t[0], 0.0), c.t[-1], 400)
            ax.plot(tt, model_tensile_force(f.material(c.length), tt, c.speed),
                    color=_COLOURS[m], lw=1, label=m if i == 0 else None)
    ax.legend(fontsize=8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("F [N]")


def _joint_residuals(ax, result: JointIdentification, m: str) -> None:
    f, data = result.fits[m], result.data
    ax.set_title(f"{m}: AIC {f.aic:.1f}, BIC {f.bic:.1f}", fontsize=9)
    for i, c in enumerate(data.curves):
        w = data.noise_rel * np.abs(c.zeroed_force) + data.noise_abs
        Fm = model_tensile_force(f.material(c.length), c.t, c.speed) + f.offsets[i].value
        sig = f.blocks[0].sigma if f.blocks else 1.0
        ax.plot(c.t, (c.force - Fm) / (w * sig), ".", ms=1.5, color=_COLOURS[m])
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("tensile residual [noise sd]")


def _joint_creep_tests(ax, result: JointIdentification) -> None:
    cr = result.data.residuals
    assert cr is not None
    ax.set_title("creep tests (Eq. 10)")
    compliance = cr.residual / (cr.force * cr.t1) * cr.length / SPECIMEN_LENGTH_M
    c2 = result.params["c2"]
    ax.plot(np.arange(1, compliance.size + 1), 1.0 / compliance, "o", color="k",
            label="F t1/x per test")
    if c2.value is not None:
        ax.axhline(c2.value, color="tab:red", label=f"c2 = {c2.value:.4g} N s/m")
    if c2.ci95 is not None:
        ax.axhspan(c2.ci95[0], c2.ci95[1], color="tab:red", alpha=0.15, label="95 % interval")
    ax.set_xlabel("creep test")
    ax.set_ylabel("c2 [N s/m] (Eq. 10)")
    ax.legend(fontsize=8)


def _joint_creep_curves(ax, result: JointIdentification) -> None:
    from ..material.response import force_response
    ax.set_title("creep curves and fits")
    for cc in result.data.creep_curves:
        ax.plot(cc.t, cc.elongation * 1e3, ".", ms=2, color="k")
        for m, f in result.fits.items():
            x = force_response(f.material(cc.length), cc.t, cc.force, cc.hold).elongation
            ax.plot(cc.t, x * 1e3, color=_COLOURS[m], lw=1)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("creep elongation [mm]")


def _constants(params: dict) -> str:
    """``name = value unit`` of each identified, finite constant of ``params``."""
    return ", ".join(f"{n} = {e.value:.4g} {e.unit}" for n, e in params.items()
                     if e.value is not None and np.isfinite(e.value))


def _title(text: str, ncols: int) -> str:
    """``text`` wrapped to the figure's width (``ncols`` panels)."""
    return "\n".join(textwrap.fill(line, 62 * ncols) for line in text.split("\n"))


def plot_joint(result: JointIdentification, path: str | os.PathLike,
               tensile: Sequence[TensileCurve] = ()) -> Figure:
    """The panels the data allow, under a title, into ``path`` (PNG); returns the figure.

    With tensile curves: the curves and every model's fit [N], and each model's residuals
    [noise sd]; with creep tests: F t1 / x per test and c2 [N s/m]; with creep curves: the
    elongations [mm] and the fits.  A panel without data is left out, not drawn empty.
    """
    data = result.data
    models = list(result.fits) if data.curves else []
    bottom: list[Callable[..., None]] = []
    if data.residuals is not None:
        bottom.append(_joint_creep_tests)
    if data.creep_curves:
        bottom.append(_joint_creep_curves)
    ncols = max(len(models), len(bottom), 1)
    nrows = (2 if models else 1 if data.curves else 0) + (1 if bottom else 0)
    fig = Figure(figsize=(4.2 * ncols if ncols > 1 else 6.0, 3.4 * nrows + 0.8))
    gs = fig.add_gridspec(nrows, ncols)
    row = 0
    if data.curves:
        _joint_tensile(fig.add_subplot(gs[0, :]), result, tensile)
        row = 1
        if models:
            for j, m in enumerate(models):
                _joint_residuals(fig.add_subplot(gs[1, j]), result, m)
            row = 2
    if len(bottom) == 2:
        bottom[0](fig.add_subplot(gs[row, 0]), result)
        bottom[1](fig.add_subplot(gs[row, 1:]), result)
    elif bottom:
        bottom[0](fig.add_subplot(gs[row, :]), result)
    title = (f"identify, joint fit (model chosen by BIC): {result.model or 'not determined'}; "
             + _constants(result.params))
    if not data.curves:
        title += "\nno tensile curve: k1, c1 and the model need one (--tensile FILE)"
    fig.suptitle(_title(title, ncols), fontsize=10)
    _save(fig, path)
    return fig


def _paper_tensile(ax, result: PaperIdentification, eq5: ThreeElement | None,
                   tensile: Sequence[TensileCurve]) -> None:
    ax.set_title("tensile curves (offset removed) and Eq. 5")
    if tensile:
        _discarded(ax, list(tensile), [c.offset for c in result.curves],
                   [c.crack.keep for c in result.curves])
    for i, c in enumerate(result.curves):
        ax.plot(c.t, c.zeroed_force, ".", ms=2, color="k", label="data (kept)" if i == 0 else None)
        if eq5 is not None:
            m = eq5.scaled(c.length)
            tt = np.linspace(0.0, c.t[-1], 300)
            ax.plot(tt, tensile_force(m, tt, c.speed),
                    color="tab:red", label="Eq. 5" if i == 0 else None)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("F [N]")
    ax.legend(fontsize=8)


def _paper_regression(ax, result: PaperIdentification, eq5: ThreeElement,
                      tensile: Sequence[TensileCurve]) -> None:
    ax.set_title("Eq. 12-13: Y + b X = 0")
    X, Y = eq13_points(result.curves, eq5.c1, eq5.c2)
    ax.plot(X, Y, ".", ms=2, color="k")
    b = result.b.value
    if b is not None:
        xx = np.linspace(0.0, X.max(), 50)
        ax.plot(xx, -b * xx, color="tab:red", label=f"b = {b:.4g} 1/s")
        ax.legend(fontsize=8)
    ax.set_xlabel("X = t [s]")
    ax.set_ylabel("Y [-]")


def _paper_residuals(ax, result: PaperIdentification, eq5: ThreeElement,
                     tensile: Sequence[TensileCurve]) -> None:
    ax.set_title("residuals F - Eq. 5")
    for c in result.curves:
        m = eq5.scaled(c.length)
        p = c.pull
        ax.plot(c.t[p], c.zeroed_force[p] - tensile_force(m, c.t[p], c.speed), ".", ms=2,
                color="k")
    ax.axhline(0.0, color="tab:red", lw=0.5)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("F residual [N]")


def _paper_creep(ax, result: PaperIdentification, eq5: ThreeElement | None,
                 tensile: Sequence[TensileCurve]) -> None:
    cr = result.creep
    assert cr is not None
    ax.set_title("creep tests: residual elongation (Eq. 10)")
    ax.plot(np.arange(1, len(cr) + 1), cr.residual * 1e3, "o", color="k",
            label="residual x2(inf)")
    ax.axhline(cr.residual.mean() * 1e3, color="tab:red",
               label=f"mean; c2 = {result.c2.value:.4g} N s/m")
    ax.set_xlabel("creep test")
    ax.set_ylabel("residual elongation [mm] (0.1 m)")
    ax.legend(fontsize=8)


def _paper_title(result: PaperIdentification) -> str:
    """The figure's title: the method, the constants identified, what the data left open."""
    found = _constants({"c2": result.c2, "c1": result.c1, "k1": result.k1})
    title = (f"identify, the paper's method (Sec. 3.4): {found}; "
             f"model: {result.model or 'not determined'}")
    if not result.curves:
        title += "\nno tensile curve: k1 and c1 (Eq. 5, Eq. 12-13) need one (--tensile FILE)"
    return title


def plot_paper(result: PaperIdentification, path: str | os.PathLike,
               tensile: Sequence[TensileCurve] = ()) -> Figure:
    """The panels the data allow, under a title, into ``path`` (PNG); returns the figure.

    With tensile curves: Eq. 5 against them; with k1 and c1 identified as well: the
    Eq. 12-13 regression and the residuals F - Eq. 5 [N]; with creep tests: their residual
    elongations [mm] and c2 (Eq. 10).  A panel without data is left out, not drawn empty.
    """
    k1, c1, c2 = result.k1.value, result.c1.value, result.c2.value
    # Eq. 5's constants once k1 and c1 are identified (c2 always is: the method needs creep data)
    eq5 = None if k1 is None or c1 is None or c2 is None else ThreeElement(k1, c1, c2)
    panels: list[Callable[..., None]] = []
    if result.curves:
        panels.append(_paper_tensile)
        if eq5 is not None:
            panels += [_paper_regression, _paper_residuals]
    if result.creep is not None:
        panels.append(_paper_creep)
    ncols = min(len(panels), 2)
    nrows = -(-len(panels) // 2)
    fig = Figure(figsize=(5.5 * ncols, 4.0 * nrows + 0.8))
    fig.suptitle(_title(_paper_title(result), ncols), fontsize=10)
    for i, panel in enumerate(panels):
        panel(fig.add_subplot(nrows, ncols, i + 1), result, eq5, tensile)
    _save(fig, path)
    return fig
