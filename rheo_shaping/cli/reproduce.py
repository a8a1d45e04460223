"""``rheo-shaping reproduce``: the paper's study (Sec. 4.2 and 5) on a cell.

Runs movements 1-4 (Table 2), the movement-4 sweep over d (Fig. 18), movement
1 at half speed without the stop (Fig. 19) and test case 1 (sagging under
gravity), prints the paper's Table 2 beside ours, and with ``--out DIR``
writes the figures as PNG files there.  The independent runs go to a pool of
``--jobs`` worker processes, or wherever ``--executor`` says (a Dask cluster:
``dask://HOST:PORT``); a progress bar on stderr counts them.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from .common import (add_executor_arguments, add_params_argument, cell_from_args,
                     executor_from_args, executor_label, output_dir)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "reproduce", help="the paper's study: Table 2, Fig. 18 sweep, Fig. 19, test case 1",
        description="Run the paper's shaping study on the cell (default: the default cell of "
                    "config/cell.yaml) and print the paper's Table 2 beside ours.")
    add_params_argument(p)
    p.add_argument("--out", metavar="DIR", help="write the figures (PNG) into this folder "
                   "(created if missing; an existing folder must be empty unless --force)")
    p.add_argument("--force", action="store_true",
                   help="write into a folder that already holds files")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object instead of the tables")
    add_executor_arguments(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


class _Progress:
    """tqdm on stderr when available (and not --quiet); a no-op otherwise."""

    def __init__(self, total: int, quiet: bool):
        self.bar = None
        if not quiet:
            try:
                from tqdm import tqdm
                self.bar = tqdm(total=total, desc="movements 1-4, half speed, d sweep",
                                unit="run", file=sys.stderr, leave=False)
            except ImportError:      # pragma: no cover - tqdm is a core requirement
                self.bar = None

    def __call__(self, done: int) -> None:
        if self.bar is not None:
            self.bar.update(done)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def write_figures(study, out: Path) -> list[Path]:
    """All figures of the study into ``out``; returns their paths."""
    from ..study.plots import (plot_movement_history, plot_phase_profiles, plot_sag,
                               plot_speed_comparison,
                               plot_sweep)
    from ..study.reproduce import MOVEMENT_NAMES, PAPER
    files = []
    for k, run in study.movements.items():
        name = MOVEMENT_NAMES[int(k)]
        files.append(plot_movement_history(run, out / f"movement{k}_history.png",
                                           f"movement {k} ({name}): F_max = {run.F_max:.3f} N, "
                                           f"SF = {run.SF:.2f}, Delta = {run.delta * 1e3:.2f} mm"))
        files.append(plot_phase_profiles(run, out / f"movement{k}_profiles.png",
                                         f"movement {k} ({name}): sheet at the end of each phase "
                                         "(red: spheres touching the tool)"))
    h = study.half_speed
    files.append(plot_movement_history(h, out / "half_speed_history.png",
                                       f"movement 1 at {h.speed * 1e3:.1f} mm/s, no stop: F_max = "
                                       f"{h.F_max:.3f} N, Delta = {h.delta * 1e3:.2f} mm"))
    files.append(plot_speed_comparison(study.movements["1"], h, out / "speed_comparison.png",
                                       PAPER["delta_limit"]))
    files.append(plot_sweep(study.sweep, out / "d_sweep.png", PAPER["d_opt"],
                            study.params.material.F_break))
    files.append(plot_sag(study.sag, study.params, out / "test_case_1.png"))
    return files


def _pct(ours: float, paper: float) -> str:
    return f"{(ours / paper - 1.0) * 100:+.1f} %"


def table_lines(study) -> list[str]:
    from ..study.reproduce import MOVEMENT_NAMES, PAPER
    lines = ["Table 2: paper | ours | difference",
             f"  {'movement':<20s} {'F_max [N]':^27s}   {'SF':^17s}   {'Delta [mm]':^23s}",
             f"  {'':<20s} {'paper':>7s} {'ours':>7s} {'diff':>9s}   {'paper':>5s} {'ours':>5s} "
             f"{'diff':>5s}   {'paper':>6s} {'ours':>6s} {'diff':>9s}"]
    for k, run in study.movements.items():
        ref = PAPER["movements"][k]
        lines.append(
            f"  {k + ' ' + MOVEMENT_NAMES[int(k)]:<20s} {ref['F_max']:7.3f} {run.F_max:7.3f} "
            f"{_pct(run.F_max, ref['F_max']):>9s}   {ref['SF']:5.2f} {run.SF:5.2f} "
            f"{run.SF - ref['SF']:+5.2f}   "
            f"{ref['delta'] * 1e3:6.2f} {run.delta * 1e3:6.2f} "
            f"{(run.delta - ref['delta']) * 1e3:+6.2f} mm")
    sw = study.sweep
    i = sw.i_min
    lines += [
        "",
        f"Fig. 18 (movement 4, d from {sw.d[0] * 1e3:g} to {sw.d[-1] * 1e3:g} mm, {sw.d.size} "
        "runs):",
        f"  F_max smallest at d = {sw.d_opt * 1e3:.1f} mm (paper 14.5 mm, "
        f"{(sw.d_opt - PAPER['d_opt']) * 1e3:+.1f} mm): F_max = {sw.F_opt:.3f} N"
        + ("" if sw.interior else "  [at the end of the range]"),
        f"  at the best sampled d = {sw.d[i] * 1e3:.0f} mm: peak 1 (vertical) {sw.peak1[i]:.3f} "
        "N, "
        f"peak 2 (horizontal) {sw.peak2[i]:.3f} N ({sw.peak_gap_at_min * 100:.1f} % apart)",
        f"  movement 4 of Table 2 runs at the cell's d = {study.movements['4'].d * 1e3:.1f} mm",
    ]
    h, m1 = study.half_speed, study.movements["1"]
    lines += [
        "",
        f"Fig. 19 (movement 1 at {h.speed * 1e3:.1f} mm/s, no stop; forced deformation "
        f"{h.forced_time:.0f} s,"
        f" movement 1: {m1.forced_time:.0f} s + {m1.dwell:.0f} s stop):",
        f"  F_max = {h.F_max:.3f} N (movement 1: {m1.F_max:.3f} N), Delta = {h.delta * 1e3:.2f} "
        "mm "
        f"(paper 6.6 mm; quality limit 5 mm)",
    ]
    s = study.sag
    lines += [
        "",
        f"Test case 1 (gravity only, t = 0 to {s.time:g} s): largest displacement "
        f"{s.max_displacement * 1e3:.2f} mm ({s.relative_displacement * 100:.1f} % of the "
        f"{s.length * 1e3:.0f} mm sheet), top link tension {s.top_tension:.3f} N",
        "",
        "Checks (issue acceptance):",
    ]
    for name, ok in {**study.checks(), **study.magnitude_checks()}.items():
        lines.append(f"  [{'yes' if ok else 'NO '}] {name}")
    contacts = ", ".join(f"{k}: {r.min_contacts_forced}" for k, r in study.movements.items())
    lines.append(f"  spheres touching the tool during the stops (fewest): {contacts}")
    return lines


def run(args: argparse.Namespace) -> int:
    from ..study.reproduce import DEFAULT_D_VALUES, reproduce
    params = cell_from_args(args)
    out = output_dir(args.out, args.force, create=True)
    wall = time.perf_counter()
    with executor_from_args(args) as executor:
        progress = _Progress(len(DEFAULT_D_VALUES) + 5, args.quiet)
        try:
            study = reproduce(params, executor=executor, progress=progress)
        finally:
            progress.close()
    files = write_figures(study, out) if out is not None else []
    wall = time.perf_counter() - wall
    if args.json:
        doc = study.to_json()
        doc["figures"] = [str(f) for f in files]
        doc["wall_time_s"] = wall
        json.dump(doc, sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    print("\n".join(table_lines(study)))
    if files:
        print("")
        print(f"figures in {out}:")
        for f in files:
            print(f"  {f}")
    print(f"\nwall time {wall:.1f} s ({executor_label(args)})")
    return 0
