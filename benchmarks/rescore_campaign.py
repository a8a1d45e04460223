#!/usr/bin/env python3
"""Re-score a saved abort campaign against the current core, without re-running the nodes.

For every case of ``--campaign FILE`` (written by ``abort_campaign.py --save``)
this recomputes, with the core as it is now, the offline F_max (no monitor)
and the monitor's default threshold (``abort_ratio`` 0: lesson 4 at the
configured speed), and prints how far they moved from the saved run and
whether any case would change class (would tear, false abort, missed). Use it
after a change of the core's numerics to tell whether a campaign still
stands; a change of class means: re-run the campaign.

    PYTHONPATH=. python benchmarks/rescore_campaign.py --campaign
    benchmarks/results/abort_campaign.json
"""
from __future__ import annotations

import argparse
import json
import os
import random
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import abort_campaign as ac  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402


def _score(cell) -> tuple[float, float]:
    """(offline F_max [N], the monitor's default threshold [N]) of a cell, with the core as it
    is."""
    from rheo_shaping.safety.abort_budget import abort_horizon, configured_speed_threshold
    from rheo_shaping.params.node_params import MonitorNodeParams
    from rheo_shaping.planning.movement import run_movement

    f_off = run_movement(cell).F_max
    s = MonitorNodeParams()
    threshold, _, _ = configured_speed_threshold(cell,
                                                 abort_horizon(cell, s.detect_time, s.stop_time),
                                                 s.noise_sigma)
    return float(f_off), float(threshold)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaign", required=True, help="JSON written by abort_campaign.py --save")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args(argv)
    try:
        saved = json.loads(Path(args.campaign).read_text())
    except (OSError, ValueError) as exc:
        print(f"rescore_campaign: error: {args.campaign}: {exc}", file=sys.stderr)
        return 2
    rng = random.Random(saved["summary"].get("seed", 1))
    base = CellParams()
    runs = [r for r in saved["runs"] if "F_max_offline" in r and "threshold_N" in r]
    n = max(r["case"] for r in saved["runs"]) + 1
    cells = [ac.sample_cell(base, rng) for _ in range(n)]
    with ProcessPoolExecutor(args.jobs) as pool:
        new = list(pool.map(_score, [cells[r["case"]] for r in runs]))
    d_off = [abs(f - r["F_max_offline"]) for (f, _), r in zip(new, runs)]
    d_thr = [abs(t - r["threshold_N"]) for (_, t), r in zip(new, runs)]
    changed = []
    for (f, t), r in zip(new, runs):
        tear = f >= r["F_break"]
        false_abort = r["aborted"] and f < t
        missed = f >= t and not r["aborted"]
        # a closed-loop run whose largest tension lies between the old and the new threshold could
        # flip
        near = min(r["threshold_N"], t) <= r["largest_N"] <= max(r["threshold_N"], t)
        if (tear != r["would_tear"] or false_abort != r["false_abort"]
                or missed != r["missed"] or near):
            changed.append(r["case"])
    print(f"{len(runs)} cases of {args.campaign}")
    print(
        f"offline F_max moved: max {max(d_off):.2e} N, median "
        f"{sorted(d_off)[len(d_off) // 2]:.2e} N")
    print(
        f"default threshold moved: max {max(d_thr):.2e} N, median "
        f"{sorted(d_thr)[len(d_thr) // 2]:.2e} N")
    print(f"cases that would change class: {changed if changed else 'none'}")
    return 0 if not changed else 1


if __name__ == "__main__":
    sys.exit(main())
