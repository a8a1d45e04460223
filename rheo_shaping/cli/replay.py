"""``rheo-shaping replay``: publish a record back into ROS on its own stamps."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ..units import NS
from . import UserError
from .common import ros_namespace


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


class _Progress:
    """A bar of the recorded seconds replayed, with an ETA, on stderr.

    The replay (nodes/replay.replay) sends each message at its stamp on the wall clock
    (``--rate`` recorded seconds per wall second) from its first message on, and tells
    only that first moment; so the bar counts recorded time by the wall clock from then,
    and holds just short of the end until the replay returns (a machine too busy to keep
    the pace shows as a bar that waits there)."""

    def __init__(self, span_s: float, rate: float, quiet: bool):
        import threading

        from tqdm import tqdm
        self.rate, self.span, self.quiet = rate, span_s, quiet
        self.bar = tqdm(desc="replay", total=round(span_s, 1), unit="s", file=sys.stderr,
                        disable=quiet, bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} recorded s "
                        "[{elapsed}<{remaining}]")
        self.started: float | None = None
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._tick, daemon=True)
        self.thread.start()

    def say(self, msg: str) -> None:
        if self.started is None:
            self.started = time.monotonic()
        if not self.quiet:
            self.bar.write(msg, file=sys.stderr)

    def _tick(self) -> None:
        while not self.stop.wait(0.2):
            if self.started is not None:
                done = min((time.monotonic() - self.started) * self.rate, 0.999 * self.span)
                self.bar.n = round(done, 1)
                self.bar.refresh()

    def close(self, finished: bool) -> None:
        self.stop.set()
        self.thread.join()
        if finished:
            self.bar.n = self.bar.total
            self.bar.refresh()
        self.bar.close()


def _span_s(record: Path) -> float:
    """The seconds between the bag's first and last message (its metadata)."""
    from rosbags.rosbag2 import Reader
    try:
        with Reader(record) as reader:
            return reader.duration / NS
    except Exception:  # noqa: BLE001 - read_record in the replay names what is wrong
        return 0.0


def _check_record(record: Path) -> None:
    """A readable record, or a UserError naming what is wrong (before any progress bar)."""
    from ..records.bag import RecordError, read_record
    try:
        read_record(record)
    except RecordError as exc:
        raise UserError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    if not (0.0 < args.rate <= 1e4):
        raise UserError(f"--rate = {args.rate:g}: expected a value in (0, 10000]")
    _check_record(Path(args.record))
    try:
        from ..nodes.replay import replay
    except ImportError as exc:
        raise UserError(f"replay needs ROS 2 (rclpy): {exc}; use the full venv") from None
    from ..records.bag import RecordError
    bar = _Progress(_span_s(Path(args.record)), args.rate, args.quiet or args.json)
    finished = False
    try:
        result = replay(Path(args.record), namespace=ros_namespace(args.namespace), rate=args.rate,
                        clock=args.clock, progress=bar.say, wait_for_subscribers=args.wait)
        finished = True
    except RecordError as exc:
        raise UserError(str(exc)) from None
    finally:
        bar.close(finished)
    if args.json:
        print(json.dumps(result))
    else:
        counts = ", ".join(f"{n} {t}" for t, n in sorted(result["messages"].items()))
        print(f"replayed {args.record}: {counts} in {result['wall_time_s']:.1f} s")
    return 0
