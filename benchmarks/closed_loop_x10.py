#!/usr/bin/env python3
"""Does the closed loop fit the cell at x10?  Each drawn cell (the draws of
``closed_loop_nodes.py``, same seed) run once by ``rheo-shaping cell --adaptive`` at the
given real-time factor, the three nodes in one process over DDS.

Per run, from the cell's ``--json`` log of refreshes (``/shaping/estimate``'s records):

* **the refresh's CPU time** [s]: the planner worker's CPU time per refresh (estimate +
  re-plan; the increments of ``worker_cpu_s``);
* **its wall time** [s] (``refresh_wall_s``: submitted to taken) against the wall time to
  the next refresh at that factor (its spacing in process time / factor);
* **late**: refreshes whose wall time exceeded that spacing (the paced cell waits for them);
* **the worker's CPU share**: its CPU time over the run's wall time;
* **the achieved factor** of the run (a paced cell slows down while it waits).

    .venv/bin/python benchmarks/closed_loop_x10.py [--cells 8] [--seed 4310]
        [--real-time-factor 10] [--json]

Each run's wall time depends on the machine's load: the figures say what ran beside them
(the load average is printed).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_name  # noqa: E402
from closed_loop_campaign import draw  # noqa: E402
from closed_loop_nodes import cell_json  # noqa: E402
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))
from _support.domains import claim_domain_id  # noqa: E402  (stdlib only)


def run_cell(d: dict, rtf: float, folder: Path, domain: int) -> dict:
    """One adaptive cell at ``rtf``: its refreshes' CPU and wall times [s]."""
    out, run = cell_json(d, True, rtf, domain, folder)
    if out is None:
        return run
    wall = run["wall_s"]
    log = out.get("adaptive", [])
    cum = [float(e.get("worker_cpu_s", 0.0)) for e in log]
    cpu = list(np.diff([0.0] + cum))
    t = [float(e["t"]) for e in log]
    gaps = [(b - a) / rtf for a, b in zip(t, t[1:])]
    walls = [float(e.get("refresh_wall_s", float("nan"))) for e in log]
    late = sum(1 for w, g in zip(walls, gaps) if w > g)
    return {"refreshes": len(log), "cpu_s": cpu, "wall_s_refresh": walls,
            "spacing_wall_s": gaps, "late": late, "achieved_factor": out["achieved_factor"],
            "run_wall_s": out.get("wall_time_s", wall), "aborted": out["aborted"],
            "finished": out["finished"],
            "worker_cpu_share": (cum[-1] / out["wall_time_s"]) if cum and
            out.get("wall_time_s") else float("nan")}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cells", type=int, default=8, help="draws run (default 8)")
    ap.add_argument("--seed", type=int, default=4310, help="the draws' seed (default 4310)")
    ap.add_argument("--real-time-factor", type=float, default=10.0)
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    a = ap.parse_args(argv)
    if a.cells < 1:
        ap.error(f"--cells {a.cells}: expected at least 1")
    if not a.real_time_factor > 0:
        ap.error(f"--real-time-factor {a.real_time_factor}: expected > 0")
    rng = np.random.default_rng(a.seed)
    draws = [draw(rng) for _ in range(a.cells)]
    rows, loads, t0 = [], [], time.monotonic()
    domain = claim_domain_id()            # one of its own, held while this runs
    with tempfile.TemporaryDirectory() as tmp:
        for i, d in enumerate(draws):
            folder = Path(tmp) / str(i)
            folder.mkdir()
            r = run_cell(d, a.real_time_factor, folder, domain)
            loads.append(os.getloadavg()[0])
            rows.append({"draw": d, **r})
            el = time.monotonic() - t0
            msg = (r["error"][-200:] if "error" in r else
                   f"{r['refreshes']} refreshes, CPU max {max(r['cpu_s'], default=0):.3f} s, "
                   f"late {r['late']}, x{r['achieved_factor']:.1f}")
            print(f"[{i + 1}/{a.cells}] cell {i}: {msg}; ETA "
                  f"{el / (i + 1) * (a.cells - i - 1):.0f} s", file=sys.stderr, flush=True)
    ok = [r for r in rows if "error" not in r]
    cpu = [c for r in ok for c in r["cpu_s"]]
    walls = [w for r in ok for w in r["wall_s_refresh"]]
    spacing = [g for r in ok for g in r["spacing_wall_s"]]
    report = {
        "machine": f"{cpu_name()}, {os.cpu_count()} cores", "seed": a.seed,
        "cells": a.cells, "errors": len(rows) - len(ok),
        "real_time_factor": a.real_time_factor,
        "refreshes": len(cpu),
        "refresh_cpu_s_median": statistics.median(cpu) if cpu else None,
        "refresh_cpu_s_p95": float(np.quantile(cpu, 0.95)) if cpu else None,
        "refresh_cpu_s_max": max(cpu) if cpu else None,
        "refresh_wall_s_median": statistics.median(walls) if walls else None,
        "refresh_wall_s_max": max(walls) if walls else None,
        "spacing_wall_s_min": min(spacing) if spacing else None,
        "late": sum(r["late"] for r in ok),
        "achieved_factor_min": min((r["achieved_factor"] for r in ok), default=None),
        "achieved_factor_median": (statistics.median([r["achieved_factor"] for r in ok])
                                   if ok else None),
        "worker_cpu_share_max": max((r["worker_cpu_share"] for r in ok), default=None),
        "aborted": sum(1 for r in ok if r["aborted"]),
        "load_average": [min(loads), max(loads)],
    }
    if a.json:
        print(json.dumps({"report": report, "rows": rows}))
    else:
        for k, v in report.items():
            print(f"{k:28s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
