#!/usr/bin/env python3
"""Diagnose chosen cases of a family benchmark again, one after the other on one process:
each case's records drawn again from its own seed (case i of seed s is the same wherever it
runs), the diagnosis of the code at hand, the row scored as ``diagnose-benchmark`` scores it
and appended to OUT (JSON lines, each row with its ``seed``).

    python benchmarks/rediagnose_cases.py --seed 4641 --cases 20,36,78 --out OUT.jsonl \\
        [--floor benchmarks/results/issue46/floor_family_seed4601.json]

Fixed as the family runs of issue 46: the dynamic world with every form variation drawn,
N 63 / 120 s, initial state ``auto``; prints each case's verdict, its wall time and the load
average beside it.
"""
from __future__ import annotations

import argparse
import json
import time

from rheo_shaping_validation.benchmark.cases import KINDS_PATTERN, base_cell
from rheo_shaping_validation.benchmark.run import _case_task
from rheo_shaping_validation.worlds.forms import Variation

FLOOR = "benchmarks/results/issue46/floor_family_seed4601.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--cases", required=True, help="comma-separated case indices")
    ap.add_argument("--out", required=True)
    ap.add_argument("--floor", default=FLOOR)
    a = ap.parse_args()
    shared = {"seed": a.seed, "base": base_cell(63, 120.0), "pattern": KINDS_PATTERN,
              "jobs": 1, "world": "dynamic", "floor": a.floor, "initial_state": "auto",
              "variations": tuple(Variation), "always_on": ()}
    for i in (int(x) for x in a.cases.split(",")):
        t = time.monotonic()
        row = dict(_case_task(shared, i), seed=a.seed)
        with open(a.out, "a") as f:
            f.write(json.dumps(row) + "\n")
        with open("/proc/loadavg") as f:
            load = f.read().split()[:3]
        print(a.seed, i, row.get("kind"), row.get("truth"), row.get("verdict"),
              f"{time.monotonic() - t:.0f} s", "load", " ".join(load), flush=True)


if __name__ == "__main__":
    main()
