"""``rheo-shaping record``: a stand-in for a real run: the simulator, measured like a real cell."""
from __future__ import annotations

import argparse
import json
from dataclasses import replace

from ..sheet.effects import active_effects
from ..planning.movement import synthesize_record
from ..records.measurement import MeasurementParams
from ..records.bag import RecordError, write_record
from ..params.schema import ParameterError, iter_fields, validate_value
from . import UserError
from .common import add_params_argument, cell_from_args, output_dir


def add_parser(sub) -> None:
    p = sub.add_parser(
        "record", help="write a synthetic recorded run (rosbag2 MCAP + scenario.yaml)",
        description="Run the cell of --params (with the effects its 'effects' section switches "
                    "on) "
                    "and measure it like a real cell: the robot's tool pose, a vision system's "
                    "points along the sheet (not the masses) with noise, rate and dropouts, and a "
                    "load cell. Writes a record directory (docs/records.md): the bag, "
                    "scenario.yaml (the nominal cell, effects off) and truth.yaml (for "
                    "benchmarks).")
    add_params_argument(p)
    p.add_argument("--out", required=True, metavar="DIR", help="record directory to create")
    p.add_argument("--movement", type=int, choices=(0, 1, 2, 3, 4),
                   help="movement (default: the params file's)")
    p.add_argument("--seed", type=int, default=None,
                   help="noise and dropout seed (default: random)")
    for fi in iter_fields(MeasurementParams):
        flag = "--" + fi.name.replace("_", "-")
        if fi.kind is bool:
            p.add_argument(flag, dest=fi.name, action=argparse.BooleanOptionalAction,
                           default=fi.default,
                           help=f"{fi.spec.description} (default {fi.default})")
        else:
            p.add_argument(flag, dest=fi.name, type=float, default=fi.default, metavar="X",
                           help=f"{fi.spec.description} [{fi.spec.unit or '-'}] (default "
                                f"{fi.default:g}, "
                                f"range {fi.spec.range_text()})")
    p.add_argument("--force", action="store_true", help="replace an existing record directory")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def measurement_from_args(args: argparse.Namespace) -> MeasurementParams:
    values = {}
    for fi in iter_fields(MeasurementParams):
        try:
            values[fi.name] = validate_value(fi.name.replace(
                "_", "-"), getattr(args, fi.name), fi.kind, fi.spec)
        except ParameterError as exc:
            raise UserError(str(exc).replace("parameter '", "option '--")) from None
    return MeasurementParams(**values)


def run(args: argparse.Namespace) -> int:
    params = cell_from_args(args)
    if args.movement is not None:
        params = replace(params, movement=replace(params.movement, number=args.movement))
    ms = measurement_from_args(args)
    out = output_dir(args.out, args.force, record=True)
    record, run_ = synthesize_record(params, ms, seed=args.seed, name=out.name)
    try:
        write_record(record, out, truth=params, start_stamp=ms.start_stamp, force=args.force)
    except RecordError as exc:
        raise UserError(str(exc)) from None
    effects = active_effects(params)
    summary = {"record": str(out), "movement": params.movement.number,
               "duration_s": record.duration, "pose_samples": int(record.pose_t.size),
               "profile_frames": len(record.profiles),
               "points_per_frame": float(sum(len(f) for f in record.profiles)
                                         / max(len(record.profiles), 1)),
               "wrench_samples": int(record.wrench_t.size) if record.wrench_t is not None else 0,
               "effects": effects, "F_max_true": run_.F_max,
               "delta_true": run_.delta}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {out}: movement {summary['movement']}, {summary['duration_s']:.1f} s, "
              f"{summary['pose_samples']} poses, {summary['profile_frames']} profile frames "
              f"(~{summary['points_per_frame']:.0f} points), {summary['wrench_samples']} wrench "
              "samples")
        print(f"  effects on: {', '.join(effects) or 'none'}; true F_max "
              f"{run_.F_max:.4f} N, "
              f"Delta {run_.delta * 1e3:.2f} mm")
    return 0
