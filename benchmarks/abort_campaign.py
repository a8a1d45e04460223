#!/usr/bin/env python3
"""Closed-loop abort campaign: does the monitor stop every tear, and only tears?

Runs the shaping cell (simulator, planner and monitor node classes in one
process over DDS with a shared executor, ``rheo_shaping.nodes.cell.run_cell``,
faster than real time) on randomised cells:

* movement 1, 2, 3 or 4 (uniform);
* tool speed ``5 ** (u ** 2.2)`` x the nominal 1e-3 m/s, u uniform in [0, 1):
  between 1x and 5x, skewed toward 1x so that about a third of the runs
  would tear the sheet without the monitor;
* depth: the end of travel moved up to 4 mm away from the cake (up for
  movements 1 and 4, outward for 2 and 3: deeper ones pinch the sheet, which
  the planner's clearance check refuses);
* movement 4's distance d uniform in [10, 20] mm;
* material spread: k1 and c2 each x uniform [0.8, 1.2].

Each case first runs offline in the core (``run_scenario`` over the same
ruckig plan) without any monitor: ``would_tear`` when its F_max reaches
F_break. Then it runs closed loop with the monitor on its defaults (automatic
threshold, trend prediction on). Reported:

* ``tears``: closed-loop runs whose largest tension reached F_break (goal 0);
* ``false_aborts``: aborted runs whose offline F_max stayed below the
  monitor's threshold (``abort_threshold``, the ratio it actually used x
  F_break; goal 0);
* ``missed``: runs whose offline F_max reached the threshold but that were
  not aborted;
* times from the threshold crossing (offline-free: the first closed-loop
  sample at or above the threshold, or the abort when the trend prediction
  fired first) to the abort reaching the planner and to the tool at rest, and
  from the abort to rest: median, 99th percentile, max;
* ``max_tension_after_abort_N``: the largest tension after the abort.

Runs that fail (solver error, planner refusal, timeout) are counted in
``failed`` with their reasons, never dropped.

    .venv/bin/python benchmarks/abort_campaign.py [--runs 300] [--seed 1] [--jobs 2] [--json]
        [--save benchmarks/results/abort_campaign.json]

Needs the full venv (rclpy). Each case claims a ROS domain of its own on the
machine it runs on (a lock file per domain id), so cases can run on a local
process pool or on a Dask cluster (``--executor dask://HOST:PORT``).
"""
from __future__ import annotations

import argparse
import json
import os
import random
import sys
import tempfile
import time
import contextlib
from dataclasses import replace
from pathlib import Path

import numpy as np

from rheo_shaping.params.cell import CellParams

RTF = 20.0  # simulated seconds per wall second in the closed-loop runs


def _gap(later: float | None, earlier: float | None) -> float | None:
    return later - earlier if later is not None and earlier is not None else None


def stop_intervals(t_cross: float | None, abort_t: float | None,
                   rest_t: float | None) -> dict:
    """Threshold crossing to abort, crossing to rest, abort to rest [s] (None when a time is
    missing): the latencies a campaign reports."""
    return {"cross_to_abort_s": _gap(abort_t, t_cross), "cross_to_rest_s": _gap(rest_t, t_cross),
            "abort_to_rest_s": _gap(rest_t, abort_t)}


def sample_cell(base: CellParams, rng: random.Random) -> CellParams:
    """One random cell of the campaign (see the module docstring)."""
    mv, m = base.movement, base.material
    number = rng.choice((1, 2, 3, 4))
    factor = 5.0 ** (rng.random() ** 2.2)
    away = rng.uniform(0.0, 0.004)
    end = list(getattr(mv, f"end_{number}"))
    if number in (1, 4):
        end[1] += away
    else:
        end[0] += away
    kw = {f"end_{number}": tuple(end)}
    if number == 4:
        kw["d"] = rng.uniform(0.010, 0.020)
    return replace(base,
                   movement=replace(mv, number=number, speed=mv.speed * factor, **kw),
                   material=replace(m, k1=m.k1 * rng.uniform(0.8, 1.2),
                                    c2=m.c2 * rng.uniform(0.8, 1.2)))


@contextlib.contextmanager
def claimed_domain(first: int, count: int = 100):
    """Hold a ROS_DOMAIN_ID in [first, first + count) that no other case on this machine
    holds (flock on a file per id) and point this process's next rclpy context at it."""
    import fcntl
    lock_dir = Path(tempfile.gettempdir()) / "rheo_shaping-ros-domains"
    lock_dir.mkdir(exist_ok=True)
    for i in range(first, first + count):
        with open(lock_dir / f"{i % 233}.lock", "w") as fh:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                continue
            os.environ["ROS_DOMAIN_ID"] = str(i % 233)
            os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            yield i % 233
            return
    raise RuntimeError(f"no free ROS domain in {first}..{first + count - 1}")


def _campaign_task(shared: dict, item: tuple) -> dict:
    """One case on whatever worker runs it: a domain of its own, then :func:`run_case`."""
    index, cell = item
    with claimed_domain(shared["domain"]):
        return run_case(index, cell, shared["trend"])


def offline_case(index: int, cell: CellParams):
    """A case's row and its offline run without a monitor (``would_tear``); (row with
    ``failed``, None) when the plan is refused or the core fails."""
    from rheo_shaping.planning.clearance import plan_clearance
    from rheo_shaping.planning.movement import movement_plan
    from rheo_shaping.sheet.simulation import run_scenario
    mv = cell.movement
    row = {"case": index, "movement": mv.number, "speed_factor": mv.speed / 1e-3,
           "k1": cell.material.k1, "c2": cell.material.c2, "F_break": cell.material.F_break,
           "d": mv.d if mv.number == 4 else None}
    try:
        plan = movement_plan(cell)
        if plan_clearance(cell, plan.plan).gap < cell.sheet.thickness:
            return {**row, "failed": "plan refused by the clearance check"}, None
        offline = run_scenario(cell, plan)
    except (RuntimeError, ValueError) as exc:
        return {**row, "failed": f"offline: {exc}"}, None
    row["F_max_offline"] = float(offline.F_max)
    row["would_tear"] = bool(offline.F_max >= cell.material.F_break)
    return row, offline


def run_case(index: int, cell: CellParams, trend: bool = False) -> dict:
    """Offline (no monitor) and closed-loop run of one cell."""
    from rclpy.parameter import Parameter

    from rheo_shaping.params.config import dump_cell
    from rheo_shaping.nodes.cell import run_cell

    row, offline = offline_case(index, cell)
    if offline is None:
        return row
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "cell.yaml"
        path.write_text(dump_cell(cell))
        try:
            res = run_cell(path, real_time_factor=RTF, progress=None, log_level="fatal",
                           timeout=120.0 / RTF * 6 + 30,
                           overrides={"simulator": [Parameter("publish_period", value=0.0)],
                                      "monitor": [Parameter("trend_abort", value=trend)]})
        except Exception as exc:  # noqa: BLE001 - counted, never dropped
            return {**row, "failed": f"closed loop: {type(exc).__name__}: {exc}"}
    hist = np.array(res.extra["history"], dtype=float).reshape(-1, 2)
    thr = float(res.extra["abort_threshold"])
    abort_t, rest_t = res.extra["abort_time"], res.extra["rest_time"]
    crossed = hist[hist[:, 1] >= thr]
    t_cross = float(crossed[0, 0]) if crossed.size else None
    early = bool(res.aborted and abort_t is not None and (t_cross is None or abort_t < t_cross))
    if early:
        t_cross = abort_t       # the trend prediction fired before the threshold was reached
    after = hist[hist[:, 0] >= abort_t, 1] if abort_t is not None else np.zeros(0)
    row.update({
        "threshold_N": thr, "aborted": bool(res.aborted), "aborted_before_threshold": early,
        "reason": res.abort_reason,
        "largest_N": float(hist[:, 1].max()) if hist.size else 0.0,
        "finished": bool(res.finished), "wall_time_s": res.wall_time_s,
        "false_abort": bool(res.aborted and offline.F_max < thr),
        "missed": bool(offline.F_max >= thr and not res.aborted),
        **stop_intervals(t_cross, abort_t, rest_t),
        "max_tension_after_abort_N": float(after.max()) if after.size else None,
    })
    row["tore"] = bool(row["largest_N"] >= cell.material.F_break)
    return row


def _dist(values: list) -> dict:
    v = np.array([x for x in values if x is not None], dtype=float)
    if not v.size:
        return {"n": 0, "median": None, "p99": None, "max": None}
    return {"n": int(v.size), "median": float(np.median(v)), "p99": float(np.percentile(v, 99)),
            "max": float(v.max())}


def summarise(rows: list[dict], wall: float) -> dict:
    ok = [r for r in rows if "failed" not in r]
    aborted = [r for r in ok if r["aborted"]]
    after = [r["max_tension_after_abort_N"]
             for r in aborted if r["max_tension_after_abort_N"] is not None]
    out = {
        "runs": len(rows),
        "completed": len(ok),
        "failed": len(rows) - len(ok),
        "failed_reasons": sorted({r["failed"] for r in rows if "failed" in r}),
        "would_tear": sum(r["would_tear"] for r in ok),
        "tears": sum(r["tore"] for r in ok),
        "aborts": len(aborted),
        "aborted_before_threshold": sum(r["aborted_before_threshold"] for r in aborted),
        "false_aborts": sum(r["false_abort"] for r in ok),
        "missed": sum(r["missed"] for r in ok),
        "threshold_ratio_median": (float(np.median([r["threshold_N"] / r["F_break"] for r in ok]))
                                   if ok else None),
        "cross_to_abort_s": _dist([r["cross_to_abort_s"] for r in aborted]),
        "cross_to_rest_s": _dist([r["cross_to_rest_s"] for r in aborted]),
        "abort_to_rest_s": _dist([r["abort_to_rest_s"] for r in aborted]),
        "max_tension_after_abort_N": max(after) if after else None,
        "max_tension_after_abort_over_F_break": max(
            (r["max_tension_after_abort_N"] / r["F_break"] for r in aborted
             if r["max_tension_after_abort_N"] is not None), default=None),
        "wall_time_s": wall,
        "real_time_factor": RTF,
    }
    out["abort_to_rest_p99_s"] = out["abort_to_rest_s"]["p99"]
    out["cross_to_rest_p99_s"] = out["cross_to_rest_s"]["p99"]
    return out


def table(s: dict) -> str:
    lines = [f"runs {s['runs']} (completed {s['completed']}, failed {s['failed']})",
             f"would tear without the monitor   {s['would_tear']}",
             f"tears with the monitor           {s['tears']}",
             f"aborts                           {s['aborts']} ({s['aborted_before_threshold']} by "
             "the trend, before the threshold)",
             f"false aborts                     {s['false_aborts']}",
             f"missed (reached the threshold)   {s['missed']}",
             f"max tension after abort [N]      {s['max_tension_after_abort_N']}",
             "time [s]               n     median      p99      max"]
    for key in ("cross_to_abort_s", "cross_to_rest_s", "abort_to_rest_s"):
        d = s[key]
        if d["n"]:
            lines.append(
                f"{key:18s} {d['n']:5d} {d['median']:10.3f} {d['p99']:8.3f} {d['max']:8.3f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=300,
                    help="number of randomised runs (default 300)")
    ap.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="worker processes (default: all cores)")
    ap.add_argument("--executor", metavar="SPEC", default=None,
                    help="local (default), local:N, serial or dask://HOST:PORT "
                         "(rheo_shaping.parallel)")
    ap.add_argument("--domain", type=int, default=60,
                    help="first ROS domain id the cases may claim (default 60)")
    ap.add_argument("--trend", choices=("on", "off"), default="off",
                    help="the monitor's trend prediction (default off, the monitor's default)")
    ap.add_argument("--indices", metavar="I,J,...",
                    help="run only these case numbers of the seeded draw")
    ap.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    ap.add_argument("--save", metavar="FILE",
                    help="also write the summary and every run to FILE (JSON)")
    args = ap.parse_args(argv)
    if args.runs < 1 or args.jobs < 1:
        print("abort_campaign: error: --runs and --jobs must be >= 1", file=sys.stderr)
        return 2
    if args.save and Path(args.save).exists():
        print(f"abort_campaign: error: {args.save} exists: not overwritten", file=sys.stderr)
        return 2
    from tqdm import tqdm

    from rheo_shaping.parallel import executor_from_spec, run_tasks

    rng = random.Random(args.seed)
    base = CellParams()
    cells = [sample_cell(base, rng) for _ in range(args.runs)]
    chosen = range(args.runs) if not args.indices else sorted(
        {int(x) for x in args.indices.split(",")})
    t0 = time.monotonic()
    shared = {"domain": args.domain, "trend": args.trend == "on"}
    try:
        with executor_from_spec(args.executor, jobs=args.jobs) as ex, \
                tqdm(total=len(chosen), desc="abort campaign", unit="run", file=sys.stderr) as bar:
            rows = run_tasks(ex, _campaign_task, shared, [(i, cells[i]) for i in chosen],
                             bar.update, chunks_per_worker=8)
    except ValueError as exc:
        print(f"abort_campaign: error: {exc}", file=sys.stderr)
        return 2
    summary = summarise(rows, time.monotonic() - t0)
    summary.update(seed=args.seed, trend_abort=args.trend == "on")
    if args.save:
        Path(args.save).parent.mkdir(parents=True, exist_ok=True)
        Path(args.save).write_text(json.dumps({"summary": summary, "runs": rows}, indent=1))
    if args.json:
        print(json.dumps(summary))
    else:
        print(table(summary))
    good = summary["tears"] == 0 and summary["false_aborts"] == 0 and summary["failed"] == 0
    return 0 if good else 1


if __name__ == "__main__":
    raise SystemExit(main())
