#!/usr/bin/env python3
"""Figures of the closed loop (issue 43).

* ``one_cell_figure``: tension and gap against time for one cell, the fixed plan beside the
  adaptive one, the re-plans marked (``python benchmarks/closed_loop_plot.py --out F.png``
  runs the cell: movement 1, k1 and c2 x0.7, mass x1.2 unless given).
* ``campaign_figure``: the campaign's shaped rate against the material's deviation, fixed
  and adaptive, and each cell's cycle time over its offline optimum
  (closed_loop_campaign.py --plot).
"""
from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np


def one_cell_figure(fixed, adaptive, path: str, title: str = "") -> None:
    """Two panels: the largest link tension and the gap against process time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    arms = ((fixed, "tab:grey", "fixed plan"), (adaptive, "tab:blue", "adaptive"))
    for r, colour, name in arms:
        ax1.plot(r.history[0], r.history[1], color=colour, label=f"{name}: F_max "
                 f"{r.F_max:.3f} N, cycle {r.cycle_time:.0f} s")
        ax2.plot(r.gaps[0], np.asarray(r.gaps[1]) * 1e3, color=colour,
                 label=f"{name}: Delta {r.delta * 1e3:.2f} mm")
    for e in adaptive.events:
        if e.replan is not None and e.replan.changed:
            for ax in (ax1, ax2):
                ax.axvline(e.t, color="tab:blue", lw=0.6, ls=":")
    ax1.axhline(adaptive.F_abort, color="tab:red", ls="--", label="monitor threshold")
    ax1.set_ylabel("largest link tension [N]")
    ax2.axhline(5.0, color="tab:red", ls="--", label="quality limit 5 mm")
    ax2.set_ylabel("gap Delta [mm]")
    ax2.set_ylim(0, 15)
    ax2.set_xlabel("process time [s] (dotted: re-plans)")
    ax1.legend(fontsize=8)
    ax2.legend(fontsize=8)
    if title:
        ax1.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def deviation(d: dict) -> float:
    """How far a draw's material is from the params file: the largest |ln factor|."""
    return max(abs(math.log(d[k])) for k in ("k1", "c2", "mass"))


def campaign_figure(results: list[dict], path: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    dev = np.array([deviation(r["draw"]) for r in results])
    edges = np.linspace(0.0, max(dev.max(), 1e-9) * 1.0001, 5)
    mid = 0.5 * (edges[:-1] + edges[1:])
    for arm, colour in (("fixed", "tab:grey"), ("adaptive", "tab:blue"),
                        ("world_fixed", "tab:olive"), ("world_adaptive", "tab:purple")):
        rows = [(deviation(r["draw"]), r[arm]["shaped"]) for r in results if arm in r]
        if not rows:
            continue
        x = np.array([a for a, _ in rows])
        y = np.array([b for _, b in rows], dtype=float)
        k = np.clip(np.digitize(x, edges) - 1, 0, len(mid) - 1)
        rate = [y[k == i].mean() if np.any(k == i) else np.nan for i in range(len(mid))]
        ax1.plot(mid * 100, np.array(rate) * 100, "o-", color=colour,
                 label=f"{arm} ({int(y.sum())}/{y.size})")
    ax1.set_xlabel("material deviation: largest |ln factor| of k1, c2, m [%]")
    ax1.set_ylabel("shaped [%] (no abort, Delta <= 5 mm)")
    ax1.set_ylim(-5, 105)
    ax1.legend(fontsize=8)
    for arm, colour in (("fixed", "tab:grey"), ("adaptive", "tab:blue")):
        pts = [(deviation(r["draw"]), r[arm]["cycle_time"] / r["optimum"]["cycle_time"],
                r[arm]["shaped"]) for r in results
               if r["optimum"]["cycle_time"] and math.isfinite(r["optimum"]["cycle_time"] or
                                                               math.nan)
               and r[arm]["cycle_time"] and math.isfinite(r[arm]["cycle_time"] or math.nan)]
        if pts:
            a = np.array(pts, dtype=float)
            ax2.scatter(a[:, 0] * 100, a[:, 1], c=colour, s=np.where(a[:, 2] > 0, 24, 8),
                        label=f"{arm} (large: shaped)")
    ax2.axhline(1.1, color="tab:red", ls="--", label="optimum + 10 %")
    ax2.set_xlabel("material deviation [%]")
    ax2.set_ylabel("cycle time / offline optimum")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv: list[str] | None = None) -> int:
    from rheo_shaping.adaptive.settle import material_cell
    from rheo_shaping.adaptive.loop import LoopConfig, run_closed_loop
    from rheo_shaping.params.cell import CellParams
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--movement", type=int, default=1)
    ap.add_argument("--factors", type=float, nargs=3, default=(0.7, 0.7, 1.2),
                    metavar=("K1", "C2", "MASS"))
    ap.add_argument("--seed", type=int, default=43)
    ap.add_argument("--out", default="docs/figures/closed_loop_cell.png")
    args = ap.parse_args(argv)
    base = CellParams()
    cell = replace(base, movement=replace(base.movement, number=args.movement))
    true = material_cell(cell, np.array([95.0, 1300.0, 0.3125]) * np.array(args.factors))
    runs = [run_closed_loop(true, cell, LoopConfig(adaptive=a, seed=args.seed))
            for a in (False, True)]
    one_cell_figure(*runs, args.out, title=f"movement {args.movement}, k1 x{args.factors[0]:g}"
                    f", c2 x{args.factors[1]:g}, mass x{args.factors[2]:g}")
    for r in runs:
        print(f"{'adaptive' if r.adaptive else 'fixed'}: F_max {r.F_max:.3f} N, Delta "
              f"{r.delta * 1e3:.2f} mm, cycle {r.cycle_time:.1f} s, shaped {r.shaped}, "
              f"re-plans {sum(1 for e in r.events if e.replan and e.replan.changed)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
