"""The diagnosis as a Markdown report (:mod:`.report_text`) and PNG figures."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def binned_means(t: np.ndarray, arc: np.ndarray, values: np.ndarray, t_bins: int = 36,
                 arc_bins: int = 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean of ``values`` in a grid of time [s] x arc length [m] bins (NaN where empty):
    the systematic part of a residual, with the per-point noise averaged out.
    Returns (time edges, arc edges, means (t_bins, arc_bins))."""
    t_edges = np.linspace(float(np.min(t)), float(np.max(t)) + 1e-9, t_bins + 1)
    a_edges = np.linspace(float(np.min(arc)), float(np.max(arc)) + 1e-12, arc_bins + 1)
    # histogramdd: what histogram2d computes, whose numpy 1.26 stubs take no float edges
    total = np.histogramdd((t, arc), (t_edges, a_edges), weights=values)[0]
    count = np.histogramdd((t, arc), (t_edges, a_edges))[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return t_edges, a_edges, mean


def binned_series(t: np.ndarray, values: np.ndarray, bins: int = 40
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per time bin [s]: centres, mean and RMS of ``values`` (NaN where a bin is empty):
    a residual's systematic part (mean) and its size (RMS) over time, legible where
    thousands of points per record are not."""
    edges = np.linspace(float(np.min(t)), float(np.max(t)) + 1e-9, bins + 1)
    k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, bins - 1)
    count = np.bincount(k, minlength=bins).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.bincount(k, values, bins) / count
        rms = np.sqrt(np.bincount(k, values ** 2, bins) / count)
    return 0.5 * (edges[:-1] + edges[1:]), mean, rms


def _after_title(diag) -> str:
    return f"baseline + {diag.verdict_name}" if diag.verdict_fit else "calibrated baseline"


def residual_map(diag, path: Path) -> None:
    """Profile residual [mm] per record: its RMS and mean per time bin for the nominal
    model and the verdict's (calibrated baseline + effect) against the noise, then the
    binned systematic means over time and arc length of both, on one colour scale."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    maps = diag.residual_maps
    fig, axes = plt.subplots(len(maps), 3, figsize=(14, 3.4 * len(maps) + 0.6), squeeze=False,
                             sharex="row", constrained_layout=True)
    lim = max(float(np.percentile(np.abs(r.profile), 99)) for _, r, _, _ in maps) * 1e3
    after_title = _after_title(diag)
    sp = diag.noise.profile_m * 1e3
    for row, (data, before, after, _) in enumerate(maps):
        t = data.record.profile_t[data.point_frame]
        held = " (holdout)" if data.record.name in diag.holdout else ""
        ax = axes[row, 0]
        for res, title, c in ((before, "nominal model", "C0"), (after, after_title, "C3")):
            tc, mean, rms = binned_series(t, res.profile * 1e3)
            ax.plot(tc, rms, "-", color=c, lw=1.4, label=f"{title}: RMS")
            ax.plot(tc, mean, ":", color=c, lw=1.2, label=f"{title}: mean")
        if math.isfinite(sp):
            ax.axhline(sp, color="k", ls="--", lw=0.8, label=f"noise {sp:.3f} mm")
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.set_ylabel("profile residual [mm]")
        ax.set_title(f"{data.record.name}{held}: per time bin, all points of a bin",
                     fontsize=9)
        if row == len(maps) - 1:             # one legend, under the last row's first panel
            ax.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.2))
        for col, (res, title) in enumerate(((before, "nominal model"), (after, after_title)), 1):
            te, ae, mean = binned_means(t, res.arc, res.profile)
            ax = axes[row, col]
            mesh = ax.pcolormesh(te, ae * 1e3, mean.T * 1e3, cmap="coolwarm", vmin=-lim,
                                 vmax=lim, shading="flat", rasterized=True)
            ax.set_title(f"{data.record.name}{held}: {title}, mean per bin", fontsize=9)
            ax.set_ylabel("arc length from the cake-top bond [mm]")
        for ax in axes[row]:
            ax.set_xlabel("time [s]")
    fig.colorbar(mesh, ax=axes[:, 1:], label="profile residual, measured - model [mm]",
                 shrink=0.8)
    fig.suptitle("Profile residual (measured - model, normal to the sheet): the nominal model "
                 f"against {after_title}; white: no measured point in the bin", fontsize=11)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def force_residual(diag, path: Path) -> bool:
    """Tool force residual [N], x and z, per record over time: the mean per time bin of
    the nominal model's and the verdict's, against the load cell's noise. False (nothing
    written) when no record has a tool force."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    maps = [m for m in diag.residual_maps if m[0].record.has_wrench and m[1].force is not None]
    if not maps:
        return False
    after_title = _after_title(diag)
    sf = diag.noise.force_N
    fig, axes = plt.subplots(len(maps), 2, figsize=(12, 2.9 * len(maps) + 0.6), squeeze=False,
                             sharex="row", sharey="row", constrained_layout=True)
    for row, (data, before, after, _) in enumerate(maps):
        t = data.record.wrench_t
        held = " (holdout)" if data.record.name in diag.holdout else ""
        for col, axis in enumerate("xz"):
            ax = axes[row, col]
            if math.isfinite(sf):
                ax.axhspan(-sf * 1e3, sf * 1e3, color="0.88", lw=0,
                           label=f"load cell noise +-{sf * 1e3:.1f} mN")
            ax.axhline(0.0, color="0.6", lw=0.6)
            for res, title, c in ((before, "nominal model", "C0"), (after, after_title, "C3")):
                if res.force is None:
                    continue
                tc, mean, _ = binned_series(t, res.force[:, col] * 1e3, bins=60)
                ax.plot(tc, mean, "-", color=c, lw=1.3, label=f"{title}: mean per bin")
            ax.set_title(f"{data.record.name}{held}: tool force {axis}", fontsize=9)
            ax.set_xlabel("time [s]")
            ax.set_ylabel(f"F{axis} residual [mN]")
    # one legend, under the last row (in a panel it would cover a curve)
    axes[-1, 0].legend(fontsize=7, ncol=3, loc="upper left", bbox_to_anchor=(0.0, -0.22))
    fig.suptitle("Tool force residual (measured - model, force of the sheet on the tool): the "
                 f"nominal model against {after_title}", fontsize=11)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return True


def effects_chart(diag, path: Path) -> None:
    """Explained fraction of the baseline's excess misfit per candidate, fit and holdout
    records; a candidate not checked by simulation has no holdout value, and says so."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from .candidates import CHECKED, rank_key as _rank_key
    fits = sorted(diag.effects + diag.pairs, key=_rank_key)
    if not fits:
        return
    names = ["+".join(f.names) for f in fits]
    fit = np.array([diag.explained(f) for f in fits], float)
    hold = np.array([diag.explained(f, True) for f in fits], float)
    y = np.arange(len(fits))
    fig, ax = plt.subplots(figsize=(8, 0.4 * len(fits) + 1.9))
    ax.barh(y - 0.2, np.nan_to_num(fit), 0.4, label="fit records")
    ax.barh(y + 0.2, np.nan_to_num(hold), 0.4, label="holdout records")
    for k, f in enumerate(fits):
        notes = []
        if not math.isfinite(fit[k]):
            notes.append("fit: n/a (no fit)")
        if not math.isfinite(hold[k]):
            notes.append("holdout: not simulated" if not f.checked or not diag.holdout
                         else "holdout: n/a")
        if notes:
            ax.text(max(np.nan_to_num(fit[k]), 0.0) + 0.02, k, ", ".join(notes), va="center",
                    fontsize=7, color="0.35")
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.set_xlim(-0.2, 1.05)
    ax.axvline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("fraction of the calibrated baseline's excess misfit explained")
    why = (f"holdout bars: only the {CHECKED} best single effects (and the best pair, where "
           "pairs are tried) are checked by\nsimulation on the holdout records; the others are "
           "linearised fits on the fit records" if diag.holdout
           else "no holdout records: fit records only")
    ax.set_title(f"Candidate effects, best first (verdict: {diag.verdict_name})\n{why}",
                 fontsize=9)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write(diag, out_dir: Path, process: dict | None = None) -> list[Path]:
    """report.md and the PNG figures in ``out_dir``; returns their paths."""
    from .report_text import markdown
    out_dir.mkdir(parents=True, exist_ok=True)
    figs = {"profile residual over time and arc length": "residual_map.png",
            "tool force residual over time": "force_residual.png",
            "candidate effects": "effects.png"}
    residual_map(diag, out_dir / figs["profile residual over time and arc length"])
    if not force_residual(diag, out_dir / figs["tool force residual over time"]):
        figs.pop("tool force residual over time")
    effects_chart(diag, out_dir / figs["candidate effects"])
    if not (diag.effects or diag.pairs):
        figs.pop("candidate effects")
    (out_dir / "report.md").write_text(markdown(diag, figs, process))
    return [out_dir / "report.md", *(out_dir / f for f in figs.values())]
