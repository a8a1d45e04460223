"""Figures of a run: profile snapshots and tension/deformation against time.

matplotlib is imported lazily (Agg backend), so the core runs without it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..planning.scenarios import FORCED, phase_label
from ..sheet.geometry import Cake
from ..sheet.metrics import touching_tool
from ..sheet.simulation import RunResult
from ..sheet.tools import tool_shape

#: Colours of the phases shaded in time plots.
PHASE_COLOURS = {"approach": "#e8f0ff", "forced": "#ffe8e8", "dwell": "#fff6d8",
                 "release": "#e8ffe8", "settle": "#f2f2f2"}


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(plt, fig, path: str | Path, dpi: int = 120) -> Path:
    """Lay out, write and close ``fig``; the path written."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return Path(path)


def draw_cell(ax, result: RunResult, k: int, colour: str = "C0", label: str | None = None,
              tool: bool = True) -> None:
    """Draw the cake outline, the sheet (centreline + spheres) and the tool at step k."""
    p = result.params
    cake = Cake.of(p.cake)
    outline = cake.outline(200)
    ax.plot(outline[:, 0] * 1e3, outline[:, 1] * 1e3, color="saddlebrown", lw=1.5)
    ax.axhline(0.0, color="k", lw=1.0)
    nodes = result.nodes(k)
    ax.plot(nodes[:, 0] * 1e3, nodes[:, 1] * 1e3, "-o", color=colour, ms=2.5, lw=1.2, label=label)
    if tool and np.all(np.isfinite(result.tool[k])):
        t_out = tool_shape(p.tool).outline(120, offset=result.tool[k])
        t_out = np.vstack((t_out, t_out[:1]))
        ax.plot(t_out[:, 0] * 1e3, t_out[:, 1] * 1e3, color="0.4", lw=1.0)


def plot_profiles(result: RunResult, times: Sequence[float], path: str | Path,
                  title: str = "") -> Path:
    """Sheet profiles at the given times [s] in one axes, saved as PNG."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 5.0))
    for i, t in enumerate(times):
        k = int(np.argmin(np.abs(result.t - t)))
        draw_cell(ax, result, k, f"C{i}", f"t = {result.t[k]:.1f} s")
    ax.set_aspect("equal")
    ax.set_xlim(-0.045e3, 0.08e3)
    ax.set_ylim(-0.005e3, result.params.cake.height * 1e3 + 0.04e3)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title(title or "sheet profile")
    return _save(plt, fig, path)


def plot_history(result: RunResult, path: str | Path, link: int | None = None,
                 phases: Sequence[tuple[float, float, str]] = (), title: str = "") -> Path:
    """Tension of the most stressed link and its total, elastic and plastic deformation.

    Like the paper's Figs. 16-17: ``phases`` are (t_start, t_end, name) spans
    shaded in the background.
    """
    plt = _pyplot()
    i = (result.peak.link if link is None else link) - 1
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.0, 5.5), sharex=True)
    for ax in (ax1, ax2):
        for t0, t1, name in phases:
            ax.axvspan(t0, t1, color=PHASE_COLOURS.get(name, "#f0f0f0"), lw=0)
    ax1.plot(result.t, result.tension[:, i], color="C3", label=f"tension, link {i + 1}")
    ax1.axhline(result.params.material.F_break, color="k", ls="--", lw=0.8, label="F_break")
    ax1.set_ylabel("tension [N]")
    ax1.legend(fontsize=8)
    L0 = result.rest_length[i]
    ax2.plot(result.t, (result.elastic[:, i] + result.plastic[:, i]) * 1e3, label="total")
    ax2.plot(result.t, result.elastic[:, i] * 1e3, label="elastic (spring)")
    ax2.plot(result.t, result.plastic[:, i] * 1e3, label="plastic (dashpot c2)")
    ax2.set_ylabel(f"elongation of link {i + 1} [mm]\n(rest length {L0 * 1e3:.2f} mm)")
    ax2.set_xlabel("t [s]")
    ax2.legend(fontsize=8)
    ax1.set_title(title or "tension and deformation")
    return _save(plt, fig, path)


# ------------------------------------------------------------ the paper's study
def _phase_legend(ax, phases) -> None:
    """The phases' colours as a legend in one row under ``ax`` (below its x label), where
    it covers neither the curves nor ``ax``'s own legend (kept)."""
    from matplotlib.patches import Patch
    names = []
    for _, _, n in phases:
        if n not in names:
            names.append(n)
    handles = [Patch(facecolor=PHASE_COLOURS.get(n, "#f0f0f0"), edgecolor="0.6",
                     label=phase_label(n)) for n in names]
    own = ax.get_legend()
    ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.17),
              ncol=len(handles), frameon=False, title="shaded phases", title_fontsize=7)
    if own is not None:
        ax.add_artist(own)


def plot_movement_history(run, path: str | Path, title: str = "") -> Path:
    """Figs. 16-17: tension of the most stressed link, its total, elastic and plastic
    elongation, with the phases (approach, forced, dwell, release, settle) shaded.

    ``run`` is a :class:`rheo_shaping.study.reproduce.MovementRun`.
    """
    plt = _pyplot()
    res = run.result
    i = res.peak.link - 1
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.5, 6.0), sharex=True)
    for ax in (ax1, ax2):
        for t0, t1, name in run.phases:
            ax.axvspan(t0, t1, color=PHASE_COLOURS.get(name, "#f0f0f0"), lw=0)
    ax1.plot(res.t, res.tension[:, i], color="C3", label=f"tension, link {i + 1} (most stressed)")
    ax1.plot(res.t, res.tension.max(axis=1), color="C3",
             ls=":", lw=0.8, label="largest link tension")
    ax1.axhline(res.params.material.F_break, color="k", ls="--", lw=0.8, label="F_break")
    for k, (tp, fp) in enumerate(run.peaks):
        ax1.plot([tp], [fp], "v", color="k", ms=5)
        ax1.annotate(f"{fp:.3f} N", (tp, fp), textcoords="offset points",
                     xytext=(4, 4), fontsize=7)
    ax1.set_ylabel("tension [N]")
    ax1.set_ylim(0.0, max(1.15 * res.params.material.F_break, 1.1 * res.F_max))
    ax1.legend(fontsize=7, loc="upper left")
    L0 = res.rest_length[i]
    ax2.plot(res.t, (res.elastic[:, i] + res.plastic[:, i]) * 1e3, color="C0", label="total")
    ax2.plot(res.t, res.elastic[:, i] * 1e3, color="C1", label="elastic (spring k1)")
    ax2.plot(res.t, res.plastic[:, i] * 1e3, color="C2", label="plastic (dashpot c2)")
    ax2.set_ylabel(f"elongation of link {i + 1} [mm]\n(rest length {L0 * 1e3:.2f} mm)")
    ax2.set_xlabel("t [s]")
    ax2.set_xlim(0.0, res.t[-1])
    ax2.legend(fontsize=7, loc="upper left")
    _phase_legend(ax2, run.phases)
    ax1.set_title(title or f"movement {run.label}: F_max = {res.F_max:.3f} N, "
                  f"SF = {res.SF:.2f}, Delta = {res.delta * 1e3:.2f} mm")
    return _save(plt, fig, path)


def _cell_limits(result: RunResult) -> tuple[tuple[float, float], tuple[float, float]]:
    """x and z limits [mm] that hold the cake, the sheet and the whole tool at every step."""
    p = result.params
    xs = [result.x[..., 0].max(), result.anchors[1][0]]
    zs = [p.cake.height + 0.02, float(result.x[..., 1].max()) + 0.01]
    finite = np.all(np.isfinite(result.tool), axis=1)
    if finite.any():
        outline = tool_shape(p.tool).outline(64)              # relative to the tool point
        tools = result.tool[finite]
        xs.append(min(float(tools[:, 0].max() + outline[:, 0].max()), 0.15))
        zs.append(min(float(tools[:, 1].max() + outline[:, 1].max()) + 0.003, 0.2))
    x_hi = max(xs) + 0.005
    x_lo = min(result.anchors[0][0], -p.cake.fillet_radius) - 0.01
    return (x_lo * 1e3, x_hi * 1e3), (-3.0, max(zs) * 1e3)


def plot_phase_profiles(run, path: str | Path, title: str = "") -> Path:
    """The sheet and tool at t = 0 and at the end of every phase, one panel each."""
    plt = _pyplot()
    res = run.result
    times = [0.0] + [b for _, b, _ in run.phases]
    names = ["start"] + [n for _, _, n in run.phases]
    n = len(times)
    cols = min(n, 4)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.3 * cols, 3.1 * rows), squeeze=False)
    xlim, zlim = _cell_limits(res)
    for ax, t, name in zip(axes.flat, times, names):
        k = int(np.argmin(np.abs(res.t - t)))
        draw_cell(ax, res, k, "C0")
        touching = touching_tool(res.tool_contact[k])
        if touching.any():
            ax.plot(res.x[k, touching, 0] * 1e3, res.x[k, touching, 1]
                    * 1e3, "o", color="C3", ms=3.5)
        ax.set_aspect("equal")
        ax.set_xlim(*xlim)
        ax.set_ylim(*zlim)
        ax.set_title(f"end of {phase_label(name)}, t = {res.t[k]:.1f} "
                     "s" if name != "start" else "t = 0",
                     fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("x, out from the cake wall [mm]", fontsize=7)
        ax.set_ylabel("z, up from the workplane [mm]", fontsize=7)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.suptitle(
        title or f"movement {run.label}: profiles (red: spheres touching the tool)", fontsize=9)
    return _save(plt, fig, path, dpi=110)


def plot_sweep(sweep, path: str | Path, d_paper: float | None = None, F_break: float | None = None,
               title: str = "") -> Path:
    """Fig. 18: movement 4's F_max and its two force peaks against d."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    ax.plot(sweep.d * 1e3, sweep.F_max, "o-", color="C3", ms=3.5, label="F_max")
    ax.plot(sweep.d * 1e3, sweep.peak1, "--", color="C0", label="peak 1 (vertical step)")
    ax.plot(sweep.d * 1e3, sweep.peak2, "--", color="C2", label="peak 2 (horizontal step)")
    ax.axvline(sweep.d_opt * 1e3, color="C3", lw=0.8,
               label=f"our minimum d = {sweep.d_opt * 1e3:.1f} mm ({sweep.F_opt:.3f} N)")
    if d_paper is not None:
        ax.axvline(d_paper * 1e3, color="k", ls=":", lw=0.8,
                   label=f"paper d = {d_paper * 1e3:.1f} mm")
    if F_break is not None:
        ax.axhline(F_break, color="k", ls="--", lw=0.8, label="F_break")
    ax.set_xlabel("d, tool's distance from the cake in the vertical step [mm]")
    ax.set_ylabel("tension [N]")
    ax.legend(fontsize=7)
    ax.set_title(title or "movement 4: maximum tension against d (Fig. 18)")
    return _save(plt, fig, path)


def plot_speed_comparison(full, half, path: str | Path, delta_limit: float | None = None) -> Path:
    """Fig. 19 against movement 1: tension histories, and the sheet at the end near the cake's
    foot."""
    plt = _pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11.0, 4.2),
                                   gridspec_kw={"width_ratios": [1.6, 1.0]})
    for run, c in ((full, "C0"), (half, "C1")):
        r = run.result
        i = r.peak.link - 1
        ax1.plot(r.t, r.tension[:, i], color=c,
                 label=f"{run.speed * 1e3:.1f} mm/s, stop {run.dwell:.0f} s: F_max {r.F_max:.3f} "
                       "N, "
                       f"Delta {r.delta * 1e3:.2f} mm")
        for t0, t1, name in run.phases:
            if name == FORCED:
                ax1.axvspan(t0, t1, color=c, alpha=0.08, lw=0)
    ax1.axhline(full.result.params.material.F_break, color="k", ls="--", lw=0.8, label="F_break")
    ax1.set_xlabel("t [s] (shaded: forced deformation)")
    ax1.set_ylabel("tension of the most stressed link [N]")
    ax1.legend(fontsize=7)
    ax1.set_title("movement 1 at full and half tool speed (Fig. 19)", fontsize=9)
    p = full.result.params
    cake = Cake.of(p.cake)
    out = cake.outline(200)
    ax2.plot(out[:, 0] * 1e3, out[:, 1] * 1e3, color="saddlebrown", lw=1.5)
    ax2.axhline(0.0, color="k", lw=1.0)
    for run, c in ((full, "C0"), (half, "C1")):
        nodes = run.result.nodes(-1)
        ax2.plot(nodes[:, 0] * 1e3, nodes[:, 1] * 1e3, "-o", color=c, ms=3,
                 label=f"{run.speed * 1e3:.1f} mm/s: Delta {run.result.delta * 1e3:.2f} mm")
    zc = 2.0 * p.sheet.thickness * 1e3
    ax2.axhline(zc, color="0.5", ls=":", lw=0.8, label="Delta is measured below this height")
    if delta_limit is not None:
        # the curves are centrelines: Delta = 5 mm puts the centreline half a thickness further out
        x_lim = (delta_limit + 0.5 * p.sheet.thickness) * 1e3
        ax2.plot([x_lim, x_lim], [0.0, zc], color="r", ls="--", lw=1.0,
                 label="quality limit (centreline at Delta = 5 mm)")
    ax2.set_xlim(-5, 40)
    ax2.set_ylim(-2, 40)
    ax2.set_aspect("equal")
    ax2.set_xlabel("x [mm]")
    ax2.set_ylabel("z [mm]")
    ax2.legend(fontsize=7)
    ax2.set_title(f"sheet at t = {full.result.t[-1]:.0f} s near the cake's foot", fontsize=9)
    fig.suptitle(f"Fig. 19: movement 1 at {full.speed * 1e3:.1f} and {half.speed * 1e3:.1f} "
                 "mm/s: the most stressed link's tension (left) and where the sheet ends "
                 "at the cake's foot (right)", fontsize=10)
    return _save(plt, fig, path)


def plot_sag(sag, params, path: str | Path) -> Path:
    """Test case 1: the undeformed drape (t = 0) and the sheet after sagging under gravity."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.6))
    cake = Cake.of(params.cake)
    out = cake.outline(200)
    ax.plot(out[:, 0] * 1e3, out[:, 1] * 1e3, color="saddlebrown", lw=1.5)
    ax.axhline(0.0, color="k", lw=1.0)
    ax.plot(sag.undeformed[:, 0] * 1e3, sag.undeformed[:, 1] * 1e3, "-o", ms=3, color="C0",
            label="t = 0 (undeformed drape)")
    ax.plot(sag.sagged[:, 0] * 1e3, sag.sagged[:, 1] * 1e3, "-o", ms=3, color="C1",
            label=f"t = {sag.time:g} s (gravity only)")
    ax.set_aspect("equal")
    pts = np.vstack((sag.undeformed, sag.sagged)) * 1e3
    ax.set_xlim(pts[:, 0].min() - 10.0, pts[:, 0].max() + 10.0)
    ax.set_ylim(-3.0, pts[:, 1].max() + 10.0)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    ax.legend(fontsize=8)
    ax.set_title(f"test case 1: largest displacement {sag.max_displacement * 1e3:.2f} mm "
                 f"({sag.relative_displacement * 100:.1f} % of the sheet length)", fontsize=9)
    return _save(plt, fig, path)
