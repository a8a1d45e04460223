"""The initial state from the records, on effect-free records of the dynamic world.

For each effect-free case of ``diagnose-benchmark --world dynamic`` (its own seed, the
benchmark's draws), the calibrated baseline's excess misfit J - 1 on fit and holdout
records and the share of it that lies before the tool first touches the sheet
(``before_contact``: profile frames before the contact time read from the records, force
samples before it; balanced as J), once with the scenario's settled drape as the initial
state and once with the state read from the records (``initial_state.estimate``).

    python benchmarks/initial_state_study.py --seed 11 --cases 4 [--n-masses 31]
        [--process-time 70] [--modes settled,auto] [--json]
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np


def before_contact_share(diag, data_by_name: dict) -> dict:
    """J - 1 of the baseline on the fit records and the share of it before contact."""
    from rheo_shaping.diagnosis.initial_state import contact_time
    sp, sf = diag.noise.profile_m, diag.noise.force_N
    fit = set(diag.records)
    num_p = den_p = num_f = den_f = 0.0
    n_p = n_f = 0
    for d, _nom, res, _run in diag.residual_maps:
        if d.record.name not in fit:
            continue
        tc = contact_time(d.record)
        t_pt = d.record.profile_t[d.point_frame]
        e = res.profile ** 2 / sp ** 2 - 1.0
        num_p += float(np.sum(e[t_pt < tc]))
        den_p += float(np.sum(e))
        n_p += e.size
        if res.force is not None:
            ef = np.sum(res.force ** 2, axis=1) / (2 * sf ** 2) - 1.0
            num_f += float(np.sum(ef[d.record.wrench_t < tc]))
            den_f += float(np.sum(ef))
            n_f += ef.size
    before = 0.5 * (num_p / max(n_p, 1) + (num_f / n_f if n_f else 0.0))
    total = 0.5 * (den_p / max(n_p, 1) + (den_f / n_f if n_f else 0.0))
    return {"excess_fit": total, "excess_before_contact": before,
            "before_contact_share": before / total if total > 0 else math.nan}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--cases", type=int, default=4, help="effect-free cases")
    ap.add_argument("--n-masses", type=int, default=31)
    ap.add_argument("--process-time", type=float, default=70.0)
    ap.add_argument("--modes", default="settled,auto")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    from rheo_shaping_validation.benchmark import base_cell, make_case
    from rheo_shaping.diagnosis.engine import diagnose
    base = base_cell(a.n_masses, a.process_time)
    rows = []
    for k in range(a.cases):
        index = [1, 5][k % 2] + 10 * (k // 2)
        case = make_case(index, "none", a.seed, base, world="dynamic")
        for mode in a.modes.split(","):
            t0 = time.monotonic()
            diag = diagnose(case["records"][:2], case["records"][2:], library=(),
                            jobs=a.jobs, initial_state=mode, floor="numerics")
            row = {"index": index, "mode": mode, "movements": case["movements"],
                   "lay": case["lay"], "J_base": diag.J_base,
                   "J_base_holdout": diag.J_base_holdout, "p_gap": diag.p_gap,
                   "wall_s": time.monotonic() - t0,
                   **before_contact_share(diag, {})}
            g = diag.gap_baseline.as_json()["fit"] or {}
            row["profile_sys_rms_m"] = g.get("profile_systematic_m")
            row["force_sys_rms_N"] = g.get("force_systematic_N")
            rows.append(row)
            if not a.json:
                print(f"case {index} {mode:8s} J-1 fit {diag.J_base - 1:.3f} holdout "
                      f"{diag.J_base_holdout - 1:.3f} before contact "
                      f"{row['before_contact_share']:.2f} ({row['wall_s']:.0f} s)", flush=True)
    if a.json:
        json.dump({"seed": a.seed, "n_masses": a.n_masses, "process_time_s": a.process_time,
                   "rows": rows}, sys.stdout, indent=1, default=float)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
