"""``rheo-shaping import-csv``: a record directory from CSV tables (docs/records.md)."""
from __future__ import annotations

import argparse

from ..records.csv_import import import_csv
from ..records.bag import RecordError, write_record
from . import UserError
from .common import output_dir


def add_parser(sub) -> None:
    p = sub.add_parser("import-csv", help="make a record directory from CSV tables",
                       description="Turn a real cell's CSV tables (pose t,x,z; profile t,x,z one "
                                   "row "
                                   "per point; optional wrench t,fx,fz) and the nominal cell's "
                                   "params "
                                   "file into a record directory (rosbag2 MCAP + scenario.yaml) "
                                   "that "
                                   "`rheo-shaping diagnose` reads. Formats: docs/records.md.")
    p.add_argument("--scenario", required=True, metavar="FILE",
                   help="params YAML of the nominal cell")
    p.add_argument("--pose", required=True, metavar="CSV", help="tool pose table t,x,z [s, m]")
    p.add_argument("--profile", required=True, metavar="CSV",
                   help="vision points table t,x,z [s, m]")
    p.add_argument("--wrench", metavar="CSV", help="tool force table t,fx,fz [s, N] (optional)")
    p.add_argument("--out", required=True, metavar="DIR", help="record directory to create")
    p.add_argument("--force", action="store_true", help="replace an existing record directory")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    out = output_dir(args.out, args.force, record=True)
    try:
        record = import_csv(args.scenario, args.pose, args.profile, args.wrench, name=out.name)
        write_record(record, out, force=args.force)
    except RecordError as exc:
        raise UserError(str(exc)) from None
    summary = {"record": str(out), "pose_samples": int(record.pose_t.size),
               "profile_frames": len(record.profiles),
               "wrench_samples": int(record.wrench_t.size) if record.wrench_t is not None else 0,
               "duration_s": record.duration}
    if args.json:
        import json
        print(json.dumps(summary))
        return 0
    print(f"wrote {out}: {summary['pose_samples']} poses, {summary['profile_frames']} profile "
          f"frames, {summary['wrench_samples']} wrench samples, {record.duration:.1f} s")
    return 0
