"""Figures of a run: profile snapshots and tension/deformation against time.

matplotlib is imported lazily (Agg backend), so the core runs without it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .geometry import Cake
from .simulation import RunResult
from .tools import tool_shape

#: Colours of the phases shaded in time plots.
PHASE_COLOURS = {"approach": "#e8f0ff", "forced": "#ffe8e8", "dwell": "#fff6d8",
                 "release": "#e8ffe8", "settle": "#f2f2f2"}


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def draw_cell(ax, result: RunResult, k: int, colour: str = "C0", label: str | None = None,
              tool: bool = True) -> None:
    """Draw the cake outline, the sheet (centreline + spheres) and the tool at step k."""
    p = result.params
    cake = Cake(p.cake.height, p.cake.fillet_radius, p.cake.radius)
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
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


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
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
