"""The diagnosis as a Markdown report and PNG figures."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def residual_map(diag, path: Path) -> None:
    """Residual [mm] over time and arc length, nominal model beside the verdict's, per record."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    maps = diag.residual_maps
    fig, axes = plt.subplots(len(maps), 2, figsize=(11, 3.2 * len(maps)), squeeze=False,
                             sharex="row", sharey="row", constrained_layout=True)
    lim = max(float(np.percentile(np.abs(r.profile), 99)) for _, r, _, _ in maps) * 1e3
    for row, (data, before, after, _) in enumerate(maps):
        t = data.record.profile_t[data.point_frame]
        for col, (res, title) in enumerate(((before, "nominal model"),
                                            (after, f"with {diag.verdict}" if diag.verdict_fit else "no effect added"))):
            ax = axes[row, col]
            sc = ax.scatter(t, res.arc * 1e3, c=res.profile * 1e3, s=1, cmap="coolwarm", vmin=-lim, vmax=lim,
                            rasterized=True, linewidths=0)
            held = " (holdout)" if data.record.name in diag.holdout else ""
            ax.set_title(f"{data.record.name}{held}: {title}", fontsize=9)
            ax.set_xlabel("time [s]")
            if col == 0:
                ax.set_ylabel("arc length from the cake-top bond [mm]")
    fig.colorbar(sc, ax=axes, label="profile residual, measured - model [mm]", shrink=0.8)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def effects_chart(diag, path: Path) -> None:
    """Explained fraction of the excess misfit per candidate, fit and holdout records."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fits = sorted(diag.effects + diag.pairs, key=lambda f: f.score)
    if not fits:
        return
    names = ["+".join(f.names) for f in fits]
    fit = [diag.explained(f) for f in fits]
    hold = [diag.explained(f, True) for f in fits]
    y = np.arange(len(fits))
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(fits) + 1.2))
    ax.barh(y - 0.2, np.nan_to_num(fit), 0.4, label="fit records")
    ax.barh(y + 0.2, np.nan_to_num(hold), 0.4, label="holdout records")
    ax.axvline(0.85, color="k", lw=0.8, ls="--")
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.set_xlim(-0.2, 1.05)
    ax.set_xlabel("fraction of the gap beyond noise explained (1 - (J - 1)/(J0 - 1))")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _fmt(v, scale=1.0, digits=3):
    return "n/a" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v * scale:.{digits}f}"


def markdown(diag, figures: dict) -> str:
    j = diag.to_json()
    lines = ["# Sim-to-real gap diagnosis", "",
             f"Records fitted: {', '.join(diag.records)}; held out: {', '.join(diag.holdout) or 'none'}.",
             f"Noise estimated from the records: profile {diag.noise['profile_m'] * 1e3:.3f} mm, "
             f"tool force {diag.noise['force_N']:.4f} N. Misfit of the nominal model J0 = {diag.J0:.3f} "
             f"(1 = within noise) on the fit records, {_fmt(diag.J0_holdout)} on the holdout.", "",
             f"## Verdict: **{diag.verdict}**", ""]
    if diag.verdict_fit:
        for n, vals in diag.verdict_fit.values.items():
            from ..effects import EFFECTS
            e = EFFECTS[n]
            for k, v in enumerate(vals):
                lo, hi = diag.verdict_fit.interval[n][k]
                lines.append(f"- {n}.{e.fit[k]} = {v:.4g} {e.unit[k]} (95 % interval {lo:.4g} .. {hi:.4g})")
        lines.append("")
    elif diag.verdict == "none":
        lines += ["The nominal model agrees with the records within the measurement noise.", ""]
    else:
        lines += ["No candidate effect accounts for the gap beyond noise (none explains "
                  "enough of it on the fit and holdout records); the best candidates are listed below.", ""]
    lines += ["## Where the model parts from the records (nominal model)", "",
              "| rank | kind | where | n | RMS | systematic RMS | x noise | mean |", "|---|---|---|---|---|---|---|---|"]
    for w in diag.where:
        s = 1e3 if w["unit"] == "m" else 1.0
        u = "mm" if w["unit"] == "m" else "N"
        lines.append(f"| {w['rank']} | {w['kind']} | {w['name']} | {w['n']} | {_fmt(w['rms'], s)} {u} | "
                     f"{_fmt(w['systematic_rms'], s)} {u} | {_fmt(w['relative'], 1, 2)} | {_fmt(w['mean'], s)} {u} |")
    lines += ["", "## Which effect: candidates ranked by BIC", "",
              "| rank | effect | parameters | BIC | J fit | J holdout | explained fit | explained holdout |",
              "|---|---|---|---|---|---|---|---|"]
    for e in j["effects"]:
        params = "; ".join(f"{n} = " + ", ".join(f"{v:.4g}" for v in vals) for n, vals in e["params"].items())
        lines.append(f"| {e['rank']} | {e['name']} | {params} | {e['score']:.1f} | {e['J_fit']:.3f} | "
                     f"{_fmt(e['J_holdout'])} | {_fmt(e['explained_fit'])} | {_fmt(e['explained_holdout'])} |")
    lines += ["", "## How far the gap shrinks", "",
              "| records | figure | before | after |", "|---|---|---|---|"]
    for grp in ("fit", "holdout"):
        b, a = diag.gap_before.get(grp), diag.gap_after.get(grp)
        if not b:
            continue
        for key, label, s in (("profile_rms_m", "profile RMS [mm]", 1e3), ("profile_systematic_m", "profile systematic RMS [mm]", 1e3),
                              ("profile_max_m", "profile max [mm]", 1e3), ("profile_max_rel", "profile max / undeformed length [%]", 100),
                              ("force_rms_N", "tool force RMS [N]", 1), ("force_systematic_N", "tool force systematic RMS [N]", 1),
                              ("delta_error_m", "Delta error [mm]", 1e3), ("gap", "gap beyond noise sqrt(J - 1)", 1)):
            if key in b:
                lines.append(f"| {grp} | {label} | {_fmt(b[key], s)} | {_fmt(a[key], s)} |")
        lines.append(f"| {grp} | shrink of the gap | | {_fmt(a.get('shrink'))} |")
    lines += ["", "## Figures", ""]
    for title, name in figures.items():
        lines.append(f"![{title}]({name})")
    lines.append("")
    lines.append(f"{diag.runs} simulations.")
    return "\n".join(lines) + "\n"


def write(diag, out_dir: Path) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    figs = {"residual over time and arc length": "residual_map.png", "candidate effects": "effects.png"}
    residual_map(diag, out_dir / figs["residual over time and arc length"])
    effects_chart(diag, out_dir / figs["candidate effects"])
    if not (diag.effects or diag.pairs):
        figs.pop("candidate effects")
    (out_dir / "report.md").write_text(markdown(diag, figs))
    return [out_dir / "report.md", *(out_dir / f for f in figs.values())]
