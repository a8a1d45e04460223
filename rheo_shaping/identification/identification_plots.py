"""Residual plots of an identification (matplotlib, Agg canvas, no pyplot state).

They are what validates the material model: a model that fits leaves
residuals without structure, a wrong one leaves a trend (a Maxwell fit of a
Burgers material, for instance, shows a systematic wave at the start of the
pull).
"""
from __future__ import annotations

import os
from typing import Sequence

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


def plot_joint(result: JointIdentification, path: str | os.PathLike,
               tensile: Sequence[TensileCurve] = ()) -> None:
    """Data and fits of every model, their residuals, and the creep data, into ``path`` (PNG)."""
    fits = result.fits
    data = result.data
    models = list(fits)
    ncol = max(len(models), 1)
    fig = Figure(figsize=(4.2 * ncol, 10.0))
    gs = fig.add_gridspec(3, ncol)
    ax = fig.add_subplot(gs[0, :])
    ax.set_title(
        "tensile curves (fitted offset removed; grey: after crack) and fits; chosen: "
        f"{result.model}")
    if data.curves:
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
                        color=_COLOURS[m],
                        lw=1, label=m if i == 0 else None)
        ax.legend(fontsize=8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("F [N]")
    for j, m in enumerate(models):
        f = fits[m]
        ax = fig.add_subplot(gs[1, j])
        ax.set_title(f"{m}: AIC {f.aic:.1f}, BIC {f.bic:.1f}", fontsize=9)
        for i, c in enumerate(data.curves):
            w = data.noise_rel * np.abs(c.zeroed_force) + data.noise_abs
            Fm = model_tensile_force(f.material(c.length), c.t, c.speed) + f.offsets[i].value
            sig = f.blocks[0].sigma if f.blocks else 1.0
            ax.plot(c.t, (c.force - Fm) / (w * sig), ".", ms=1.5, color=_COLOURS[m])
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("tensile residual [noise sd]")
    ax = fig.add_subplot(gs[2, 0])
    if data.residuals is not None:
        cr = data.residuals
        compliance = cr.residual / (cr.force * cr.t1) * cr.length / SPECIMEN_LENGTH_M
        c2 = result.params["c2"]
        ax.plot(np.arange(1, compliance.size + 1), 1.0 /
                compliance, "o", color="k", label="F t1/x per test")
        if c2.value is not None:
            ax.axhline(c2.value, color="tab:red", label=f"c2 = {c2.value:.4g} N s/m")
        lo, hi = c2.ci95 if c2.ci95 is not None else (None, None)
        if lo is not None and hi is not None:
            ax.axhspan(lo, hi, color="tab:red", alpha=0.15, label="95 % interval")
        ax.set_xlabel("creep test")
        ax.set_ylabel("c2 [N s/m] (Eq. 10)")
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no creep residuals", ha="center", va="center", transform=ax.transAxes)
    if data.creep_curves and ncol > 1:
        from ..material.response import force_response
        ax = fig.add_subplot(gs[2, 1:])
        for cc in data.creep_curves:
            ax.plot(cc.t, cc.elongation * 1e3, ".", ms=2, color="k")
            for m, f in fits.items():
                x = force_response(f.material(cc.length), cc.t, cc.force, cc.hold).elongation
                ax.plot(cc.t, x * 1e3, color=_COLOURS[m], lw=1)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("creep elongation [mm]")
    _save(fig, path)


def plot_paper(result: PaperIdentification, path: str | os.PathLike,
               tensile: Sequence[TensileCurve] = ()) -> None:
    """Eq. 5 against the curves, the Eq. 12-13 regression, residuals, creep spread, into
    ``path``."""
    fig = Figure(figsize=(11.0, 8.0))
    axs = fig.subplots(2, 2)
    k1, c1, c2, b = result.k1.value, result.c1.value, result.c2.value, result.b.value
    # Eq. 5's constants once k1 and c1 are identified (c2 always is: the method needs creep data)
    eq5 = None if k1 is None or c1 is None or c2 is None else ThreeElement(k1, c1, c2)
    ax = axs[0, 0]
    ax.set_title("tensile curves (offset removed) and Eq. 5")
    if tensile:
        _discarded(ax, list(tensile), [c.offset for c in result.curves], [
                   c.crack.keep for c in result.curves])
    for i, c in enumerate(result.curves):
        ax.plot(c.t, c.zeroed_force, ".", ms=2, color="k", label="data (kept)" if i == 0 else None)
        if eq5 is not None:
            m = eq5.scaled(c.length)
            tt = np.linspace(0.0, c.t[-1], 300)
            ax.plot(tt, tensile_force(m, tt, c.speed),
                    color="tab:red", label="Eq. 5" if i == 0 else None)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("F [N]")
    if result.curves:
        ax.legend(fontsize=8)
    ax = axs[0, 1]
    ax.set_title("Eq. 12-13: Y + b X = 0")
    if eq5 is not None and result.curves:
        X, Y = eq13_points(result.curves, eq5.c1, eq5.c2)
        ax.plot(X, Y, ".", ms=2, color="k")
        if b is not None:
            xx = np.linspace(0.0, X.max(), 50)
            ax.plot(xx, -b * xx, color="tab:red", label=f"b = {b:.4g} 1/s")
            ax.legend(fontsize=8)
    ax.set_xlabel("X = t [s]")
    ax.set_ylabel("Y [-]")
    ax = axs[1, 0]
    ax.set_title("residuals F - Eq. 5")
    if eq5 is not None:
        for c in result.curves:
            m = eq5.scaled(c.length)
            p = c.pull
            ax.plot(c.t[p], c.zeroed_force[p] - tensile_force(m,
                    c.t[p], c.speed), ".", ms=2, color="k")
        ax.axhline(0.0, color="tab:red", lw=0.5)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("F residual [N]")
    ax = axs[1, 1]
    cr = result.creep
    if cr is not None:
        ax.plot(np.arange(1, len(cr) + 1), cr.residual * 1e3,
                "o", color="k", label="residual x2(inf)")
        ax.axhline(cr.residual.mean() * 1e3, color="tab:red",
                   label=f"mean; c2 = {result.c2.value:.4g} N s/m")
        ax.set_xlabel("creep test")
        ax.set_ylabel("residual elongation [mm] (0.1 m)")
        ax.legend(fontsize=8)
    _save(fig, path)
