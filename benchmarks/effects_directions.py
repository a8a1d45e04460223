#!/usr/bin/env python3
"""What each unmodelled effect does to the default process (docs/model.md, "Effects").

Runs movement 4 of the default cell (``CellParams()``) nominally and with each
effect of the library at a typical value inside its realistic range (those of
test_effects.py::test_directions_in_the_default_process), one at a time, and
prints a markdown table: F_max change [%], Delta [mm], the largest distance
between the final profiles [mm] and the wall time of each run [s] on this
machine (one process; run it on an idle machine).

    PYTHONPATH=. python benchmarks/effects_directions.py [--json]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

try:
    import rheo_shaping  # noqa: F401
except ImportError:                                   # a source tree without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rheo_shaping.sheet.effects import EFFECTS  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.sheet.simulation import Simulation, run_scenario  # noqa: E402

#: effect name -> (value, how it is printed): typical values inside each realistic range
CASES = {
    "friction_mould": ((0.4,), "0.4"),
    "friction_tool": ((0.4,), "0.4"),
    "bending": ((4e-6,), "4e-6 N m^2"),
    "kelvin_c1": ((1000.0,), "1000 N s/m"),
    "power_law": ((0.6,), "n = 0.6"),
    "thinning": ((1.0,), "b = 1"),
    "mass_error": ((0.2,), "+0.2"),
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true",
                    help="print one JSON object instead of the table")
    args = ap.parse_args(argv)
    base = CellParams()
    plan = movement_plan(base)
    Simulation(base)                                  # settle once (cached) outside the timings
    t0 = time.perf_counter()
    nominal = run_scenario(base, plan)
    wall0 = time.perf_counter() - t0
    rows = []
    for name, (values, label) in CASES.items():
        p = EFFECTS[name].apply(base, values)
        Simulation(p)
        t0 = time.perf_counter()
        r = run_scenario(p, plan)
        wall = time.perf_counter() - t0
        rows.append({"effect": name, "value": label,
                     "F_max_change": r.F_max / nominal.F_max - 1.0, "delta_m": r.delta,
                     "profile_change_m": float(np.max(np.linalg.norm(r.x[-1] - nominal.x[-1],
                                                                     axis=1))),
                     "wall_s": wall})
    out = {"n_masses": base.sheet.n_masses,
           "nominal": {"F_max_N": nominal.F_max, "delta_m": nominal.delta,
                       "wall_s": wall0}, "effects": rows}
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print(f"movement 4 of the default cell (N = {base.sheet.n_masses}): F_max {nominal.F_max:.4f} "
          "N, "
          f"Delta {nominal.delta * 1e3:.2f} mm, {wall0:.2f} s")
    print(
        "| effect | value | F_max | Delta | largest change of the final profile | wall time "
        f"(nominal {wall0:.2f} s) |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['effect']} | {r['value']} | {r['F_max_change'] * 100:+.1f} % | "
              f"{r['delta_m'] * 1e3:.2f} mm | "
              f"{r['profile_change_m'] * 1e3:.1f} mm | {r['wall_s']:.2f} s |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
