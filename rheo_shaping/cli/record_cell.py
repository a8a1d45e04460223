"""``rheo-shaping record-cell``: a diagnosable record (bag + scenario.yaml) from a running cell."""
from __future__ import annotations

import argparse
import json

from . import UserError
from .common import add_params_argument, cell_from_args, output_dir, ros_namespace


def add_parser(sub) -> None:
    p = sub.add_parser(
        "record-cell", help="record a running cell (real or simulated) as a record directory",
        description="Subscribe to a running cell's tool/pose, sheet/measured_profile (a camera, "
                    "or the simulator's simulated one) and tool/wrench, keep them from the "
                    "process start (the first tool/command) on, and write a record directory "
                    "(docs/records.md): the rosbag2 MCAP bag on the messages' own stamps and "
                    "scenario.yaml, the nominal cell (every effect off) of --params or of the "
                    "running simulator. Start it before the cell's planner moves. It stops when "
                    "the planner is done and movement.process_time is recorded, after "
                    "--duration, when the cell falls silent, or on Ctrl-C.")
    add_params_argument(p)
    p.add_argument("--out", required=True, metavar="DIR", help="record directory to create")
    p.add_argument("--namespace", default="", metavar="NS", help="the cell's ROS namespace")
    p.add_argument("--duration", type=float, metavar="S",
                   help="stop after S seconds of process time (default: movement.process_time)")
    p.add_argument("--idle-timeout", type=float, default=5.0, metavar="S",
                   help="stop when the cell has been silent S wall-clock seconds (default 5)")
    p.add_argument("--timeout", type=float, default=3600.0, metavar="S",
                   help="give up after S wall-clock seconds (default 3600)")
    p.add_argument("--start", action="store_true",
                   help="start the cell's planner (its ~/start, for a planner with autostart "
                        "false) once the first pose and camera frame have arrived")
    p.add_argument("--force", action="store_true", help="replace an existing record directory")
    p.add_argument("--json", action="store_true", help="print one JSON object at the end")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    scenario = None
    if args.params:
        from ..sheet.effects import nominal
        scenario = nominal(cell_from_args(args))
    for name in ("duration", "idle_timeout", "timeout"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise UserError(f"--{name.replace('_', '-')} = {value:g}: expected a value > 0")
    out = output_dir(args.out, args.force, record=True)
    try:
        from ..nodes.recorder import RecordCellError, record_cell
    except ImportError as exc:
        raise UserError(f"record-cell needs ROS 2 (rclpy): {exc}; use the full venv") from None
    from ..records.bag import RecordError
    say = None if (args.quiet or args.json) else (lambda msg: print(msg, flush=True))
    try:
        path, rec = record_cell(out, namespace=ros_namespace(args.namespace), scenario=scenario,
                                duration=args.duration, idle_timeout=args.idle_timeout,
                                timeout=args.timeout, force=args.force, progress=say,
                                start=args.start)
    except (RecordCellError, RecordError) as exc:
        raise UserError(str(exc)) from None
    summary = {"record": str(path), "duration_s": rec.duration,
               "pose_samples": int(rec.pose_t.size), "profile_frames": len(rec.profiles),
               "wrench_samples": int(rec.wrench_t.size) if rec.wrench_t is not None else 0,
               "movement": rec.scenario.movement.number}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {path}: {summary['duration_s']:.1f} s, {summary['pose_samples']} poses, "
              f"{summary['profile_frames']} profile frames, {summary['wrench_samples']} wrench "
              f"samples")
    return 0
