#!/usr/bin/env python3
"""How fast a plan is sampled: the default cell's movement (120 s) at 1 kHz, vectorised
(``Plan.sample_many``) against one point at a time (``Plan.sample``), as a ratio measured in
one run (the test suite checks that both give the same samples, not how fast).

    .venv-core/bin/python benchmarks/bench_plan_sampling.py [--repeats 7] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_name  # noqa: E402

from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.planning.movement import movement_plan  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7, help="timed repeats (median quoted)")
    ap.add_argument("--rate", type=float, default=1000.0, help="sampling rate [Hz]")
    ap.add_argument("--json", action="store_true", help="one JSON object")
    args = ap.parse_args(argv)
    plan = movement_plan(CellParams()).plan
    times = np.arange(0.0, plan.duration, 1.0 / args.rate)
    vec, one = [], []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        plan.sample_many(times)
        vec.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        for t in times[::100]:
            plan.sample(t)
        one.append((time.perf_counter() - t0) * 100)   # scaled to every sample
    out = {"machine": f"{cpu_name()}, {os.cpu_count()} cores", "load_average": os.getloadavg()[0],
           "plan_duration_s": plan.duration, "samples": len(times),
           "sample_many_s_median": statistics.median(vec),
           "sample_pointwise_s_median": statistics.median(one),
           "ratio_pointwise_over_vectorised": statistics.median(one) / statistics.median(vec)}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{out['machine']} (load {out['load_average']:.1f}): {len(times)} samples of a "
              f"{plan.duration:.1f} s plan: sample_many "
              f"{out['sample_many_s_median'] * 1e3:.1f} ms, "
              f"sample one at a time {out['sample_pointwise_s_median'] * 1e3:.0f} ms (x"
              f"{out['ratio_pointwise_over_vectorised']:.0f}); median of {args.repeats}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
