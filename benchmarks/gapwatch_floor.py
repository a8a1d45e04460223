"""Calibrate the gap watch's floor on nominal runs; writes rheo_shaping/data/gapwatch_floor.json.

Each run is a stand-in of ``rheo-shaping record`` (the default cell of config/cell.yaml or
--params, no effect, the default measurement model, seed ``--seed0 + i``), written as a record,
read back and fed to the gap watch (rheo_shaping.gapwatch) of the same nominal cell.  The floor
of each statistic (profile and tool force RMS in noise units, over the window and over the run)
is 1 + --margin x (its largest value on these runs - 1); delta_bias_m is the median of
(measured Delta - model Delta) over every frame.  The acceptance campaign
(benchmarks/gapwatch_acceptance.py) uses other seeds.
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from rheo_shaping_validation.gapwatch_campaign import Case, default_shared
from rheo_shaping.gapwatch.floor import DEFAULT_FLOOR, ResidualFloor
from rheo_shaping.params.config import load_cell
from rheo_shaping.params.gapwatch_params import GapWatchNodeParams
from rheo_shaping.parallel import executor_from_spec, run_tasks

HERE = os.path.dirname(os.path.abspath(__file__))
KEYS = ("profile_window_z", "force_window_z", "profile_run_z", "force_run_z")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", default=os.path.join(HERE, "..", "config", "cell.yaml"))
    ap.add_argument("--runs", type=int, default=50, help="nominal runs (default 50)")
    ap.add_argument("--seed0", type=int, default=100000)
    ap.add_argument("--margin", type=float, default=1.25,
                    help="floor = 1 + margin x (largest - 1) (default 1.25)")
    ap.add_argument("--executor", default="local:2")
    ap.add_argument("--out", default=str(DEFAULT_FLOOR), help="the floor file to write")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    cell = load_cell(a.params)
    settings = GapWatchNodeParams()
    # a provisional floor nobody crosses: the calibration reads the statistics, not states
    big = ResidualFloor(1e9, 1e9, 1e9, 1e9, settings.window)
    shared = default_shared(cell, big, settings)
    t0 = time.monotonic()
    cases = [Case("", a.seed0 + i) for i in range(a.runs)]
    with executor_from_spec(a.executor) as ex:
        res = run_tasks(ex, _case_with_delta, shared, cases)
    wall = time.monotonic() - t0
    z = np.array([r["max_z"] for r in res])
    largest = dict(zip(KEYS, (float(v) for v in np.nanmax(z, axis=0))))
    bias = float(np.median(np.concatenate([r["delta_diffs"] for r in res])))
    floor = ResidualFloor(**{k: 1.0 + a.margin * (v - 1.0) for k, v in largest.items()},
                          window_s=settings.window, delta_bias_m=bias,
                          source=f"benchmarks/gapwatch_floor.py --runs {a.runs} --seed0 "
                                 f"{a.seed0} --margin {a.margin}: nominal runs of "
                                 f"{os.path.basename(a.params)}, default measurement model",
                          runs=a.runs)
    extra = {"largest": largest, "cpu_s_per_run": float(np.mean([r["cpu_s"] for r in res])),
             "wall_s": wall}
    floor.dump(a.out, extra)
    out = {"floor": floor.__dict__, **extra, "out": a.out}
    if a.json:
        print(json.dumps(out))
    else:
        print(f"{a.runs} nominal runs in {wall:.0f} s; largest {largest}; floor written to "
              f"{a.out}: {floor}")


def _case_with_delta(shared, case):
    from rheo_shaping_validation import gapwatch_campaign as campaign
    return campaign.run_case(shared, case, keep_delta=True)


if __name__ == "__main__":
    main()
