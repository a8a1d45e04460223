"""``rheo-shaping simulate``: one run of the cell, its key figures and plots."""
from __future__ import annotations

import argparse
import json
from dataclasses import replace


from ..planning.movement import movement_plan
from ..sheet.simulation import run_scenario
from .common import add_movement_argument, add_params_argument, cell_from_args, output_path


def add_parser(sub) -> None:
    p = sub.add_parser("simulate", help="run one shaping movement on the cell",
                       description="Run one shaping movement of the paper (Sec. 5) on the cell "
                                   "and "
                                   "print F_max [N], SF and Delta [m].")
    add_params_argument(p)
    add_movement_argument(p)
    p.add_argument("--plot", metavar="PNG", help="write profile snapshots to PNG "
                   "(and the tension history beside it, *_history.png)")
    p.add_argument("--force", action="store_true", help="overwrite existing plot files")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    params = cell_from_args(args)
    if args.movement is not None:
        params = replace(params, movement=replace(params.movement, number=args.movement))
    plot = output_path(args.plot, args.force, "plot")
    history = None
    if plot is not None:
        history = output_path(str(plot.with_name(plot.stem + "_history.png")), args.force, "plot")
    plan = movement_plan(params)
    result = run_scenario(params, plan)
    out = {"movement": params.movement.number, **result.summary()}
    if plot is not None:
        from ..study.plots import plot_history, plot_profiles
        t_end = result.t[-1]
        plot_profiles(result, [0.0, *plan.knots()[1:-1], t_end], plot,
                      f"movement {params.movement.number}")
        assert history is not None                  # named with the plot
        plot_history(result, history, title=f"movement {params.movement.number}")
        out["plots"] = [str(plot), str(history)]
    if args.json:
        print(json.dumps(out))
    else:
        print(f"movement {out['movement']}: {out['steps']} steps, {out['wall_time_s']:.2f} s wall "
              f"for {params.movement.process_time:g} s of process")
        print(
            f"  F_max = {out['F_max']:.4f} N in link {out['F_max_link']} at t = "
            f"{out['F_max_time']:.1f} s")
        print(f"  SF    = {out['SF']:.3f}  (F_break = {params.material.F_break:g} N)")
        print(f"  Delta = {out['delta'] * 1e3:.2f} mm  (quality limit 5 mm)")
        for p in out.get("plots", []):
            print(f"  wrote {p}")
    return 0
