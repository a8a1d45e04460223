"""``rheo-shaping cell``: the ROS 2 shaping cell (simulator, planner, monitor) in one process.

For users without ``ros2 launch``: the three nodes run on one executor in this
process and talk over DDS; the simulator runs faster than real time and is the
cell's clock.  Progress is printed while it runs, and at the end F_max, SF and
Delta of the process.  Needs the ROS 2 Python packages (``.venv``); the core
venv has no rclpy.
"""
from __future__ import annotations

import argparse
import json

from ..adaptive.streamed import PACED_COMMAND_TIMEOUT
from ..jsonable import json_safe
from . import UserError
from .common import add_movement_argument, add_params_argument, cell_from_args, ros_namespace


def add_parser(sub) -> None:
    p = sub.add_parser("cell", help="run the ROS 2 shaping cell (simulator, planner, monitor) in "
                                    "one process",
                       description="Run the shaping cell's ROS 2 nodes (simulator, planner, "
                                   "monitor) in "
                                   "one process, faster than real time, and print F_max [N], SF "
                                   "and "
                                   "Delta [m] of the process.  The params file is a ROS "
                                   "--params-file: "
                                   "the cell in '/**', node settings in 'simulator', 'planner', "
                                   "'monitor' sections.")
    add_params_argument(p)
    add_movement_argument(p)
    p.add_argument("--real-time-factor", type=float, default=50.0, metavar="X",
                   help="simulated seconds per wall-clock second (default 50; the run slows down "
                        "rather than skipping physics when the machine cannot keep up)")
    p.add_argument("--timeout", type=float, default=300.0, metavar="S",
                   help="give up after S wall-clock seconds (default 300)")
    p.add_argument("--namespace", default="", metavar="NS",
                   help="run the cell in ROS namespace NS (e.g. /cell2): every node, topic "
                        "and service moves there; the clock stays /clock (see --clock-topic)")
    p.add_argument("--clock-topic", default="/clock", choices=("/clock", "clock"),
                   help="where the simulated clock goes: /clock (default: where rviz2 and "
                        "ros2 bag look) or clock, the namespace's own, so that several cells "
                        "share one ROS domain")
    p.add_argument("--compare", action="store_true",
                   help="also run the core offline on the same plan and print both")
    p.add_argument("--adaptive", action="store_true",
                   help="the planner's closed loop (planner parameter adaptive: true): it "
                        "estimates the material while it shapes and re-plans the rest of the "
                        "movement (docs/closed-loop.md); this simulated cell waits for each "
                        "re-plan (planner adaptive_pace, simulator command_timeout "
                        f"{PACED_COMMAND_TIMEOUT:g} s)")
    p.add_argument("--json", action="store_true", help="print one JSON object at the end")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--verbose", action="store_true", help="show the nodes' INFO log lines too")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    params = cell_from_args(args)            # the cell part of the file, checked without ROS
    if not (0.0 < args.real_time_factor <= 1000.0):
        raise UserError(
            f"--real-time-factor = {args.real_time_factor:g}: expected a value in (0, 1000]")
    if not args.timeout > 0:
        raise UserError(f"--timeout = {args.timeout:g}: expected a value > 0")
    try:
        from ..nodes.cell import run_cell
    except ImportError as exc:
        raise UserError(f"the cell needs ROS 2 (rclpy): {exc}; use the full venv "
                        f"(python3 dev.py setup, then .venv/bin/rheo-shaping cell)") from None
    from ..params.schema import ParameterError
    say = None if (args.quiet or args.json) else (lambda msg: print(msg, flush=True))
    try:
        result = run_cell(args.params, movement=args.movement,
                          real_time_factor=args.real_time_factor, timeout=args.timeout,
                          progress=say,
                          log_level="info" if args.verbose else "warn",
                          namespace=ros_namespace(args.namespace),
                          clock_topic=args.clock_topic,
                          adaptive=args.adaptive)
    except ParameterError as exc:
        raise UserError(str(exc)) from None
    except Exception as exc:   # rcl refuses the params file, etc.
        if type(exc).__name__ in ("RCLError", "InvalidParameterValueException"):
            raise UserError(f"ROS could not use the parameters: {exc}") from None
        raise
    out = {**result.summary(), "plan_duration": result.extra["plan_duration"]}
    if args.adaptive:
        out["adaptive"] = result.extra["adaptive"]
    if args.compare:
        from dataclasses import replace
        from ..planning.movement import run_movement
        p = params
        d = result.d if result.movement == 4 else p.movement.d
        p = replace(p, movement=replace(p.movement, number=result.movement, d=d))
        offline = run_movement(p)
        out["offline"] = offline.run_summary.as_dict()
    if args.json:
        print(json.dumps(json_safe(out)))
    else:
        state = (f"ABORTED ({result.abort_reason})" if result.aborted
                 else "finished" if result.finished else f"timed out ({result.planner_state})")
        print(f"movement {result.movement}: {state}; process {result.process_time:g} s (run to "
              f"{result.extra['run_time']:.1f} s) in {result.wall_time_s:.1f} s wall, "
              f"x{result.achieved_factor:.0f} real time")
        print(
            f"  F_max = {result.F_max:.4f} N in link {result.F_max_link} at t = "
            f"{result.F_max_time:.1f} s")
        print(f"  SF    = {result.SF:.3f}  (F_break = {result.F_break:g} N)")
        print(f"  Delta = {result.delta * 1e3:.2f} mm  (quality limit 5 mm)")
        if args.adaptive:
            log = result.extra["adaptive"]
            print(f"  adaptive: {len(log)} refreshes, "
                  f"{sum(1 for e in log if e['switched'])} re-plans; the plan lasted "
                  f"{result.extra['plan_duration']:.1f} s")
        if args.compare:
            o = out["offline"]
            print(f"  offline (core, same plan): F_max = {o['F_max']:.4f} N "
                  f"({(result.F_max / o['F_max'] - 1) * 100:+.2f} %), "
                  f"SF = {o['SF']:.3f}, Delta = {o['delta'] * 1e3:.2f} mm "
                  f"({(result.delta - o['delta']) * 1e3:+.3f} mm)")
    if not result.finished:
        return 1
    return 3 if result.aborted else 0
