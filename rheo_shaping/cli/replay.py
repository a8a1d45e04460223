"""``rheo-shaping replay``: publish a record back into ROS on its own stamps."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from . import UserError
from .cell import _namespace


def add_parser(sub) -> None:
    p = sub.add_parser(
        "replay", help="publish a record directory back into ROS on its own stamps",
        description="Publish every message of a record's bag (docs/records.md) in stamp order, "
                    "paced on the stamps, with /clock at each message's stamp (planner, monitor "
                    "and RViz on use_sim_time see the recorded time), so the monitor and the "
                    "diagnostics can be exercised on recorded data.")
    p.add_argument("record", metavar="RECORD", help="record directory")
    p.add_argument("--namespace", default="", metavar="NS", help="publish into this namespace")
    p.add_argument("--rate", type=float, default=1.0, metavar="X",
                   help="pace: X recorded seconds per wall-clock second (default 1)")
    p.add_argument("--no-clock", dest="clock", action="store_false",
                   help="do not publish /clock")
    p.add_argument("--wait", type=float, default=0.0, metavar="S",
                   help="first wait up to S seconds for a subscriber on every topic")
    p.add_argument("--json", action="store_true", help="print one JSON object at the end")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if not (0.0 < args.rate <= 1e4):
        raise UserError(f"--rate = {args.rate:g}: expected a value in (0, 10000]")
    try:
        from ..nodes.recorder import replay
    except ImportError as exc:
        raise UserError(f"replay needs ROS 2 (rclpy): {exc}; use the full venv") from None
    from ..records.records import RecordError
    say = None if (args.quiet or args.json) else (lambda msg: print(msg, flush=True))
    try:
        result = replay(Path(args.record), namespace=_namespace(args.namespace), rate=args.rate,
                        clock=args.clock, progress=say, wait_for_subscribers=args.wait)
    except RecordError as exc:
        raise UserError(str(exc)) from None
    if args.json:
        print(json.dumps(result))
    else:
        counts = ", ".join(f"{n} {t}" for t, n in sorted(result["messages"].items()))
        print(f"replayed {args.record}: {counts} in {result['wall_time_s']:.1f} s")
    return 0
