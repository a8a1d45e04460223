#!/usr/bin/env python3
"""The attack campaign: every attack of test/nodes/test_attacks*.py, N runs each with random
timing, at x1 and x10 simulated time (docs/safety.md, "The attack campaign").

Each run is one pytest run of one attack test against the three node processes, with the
attack's start drawn per run (``RHEO_ATTACK_SEED``: uniform in [2, 14] s of process time)
and the real-time factor set (``RHEO_ATTACK_RTF``).  A run counts as a **tear** when the
simulator's own F_max (every step, from its /diagnostics) reached F_break, as a
**traceback** when any process printed one; every other failure of the test's checks
(a reason not named, a limit missed) is counted apart with its message.  The figures
(F_max median / max per attack, the frozen monitor's detection time) are printed as JSON.

    .venv/bin/python benchmarks/attack_campaign.py [--runs 50] [--rates 1,10] [--seed 1]
        [-k ATTACK] [--jobs 1] [--json OUT]

The full output of every failed run (each node's log) goes to OUT's name with ``.logs``
(``attack_campaign.logs/`` without ``--json``), one file per run.

``--jobs`` runs that many attacks at once, each in a ROS domain of its own (claimed like the
test suite's, so concurrent runs on the machine never see each other): a busier machine
than one run at a time, which is reported with the figures (the load average).

Run it with ``python3 dev.py``'s environment (a ROS_DOMAIN_ID of its own):
``.venv/bin/python benchmarks/attack_campaign.py`` from the repository root.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import random
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_name  # noqa: E402
sys.path.insert(0, str(REPO / "test"))
from _support.domains import claim_domain_id  # noqa: E402  (stdlib only)
OLD = "test/nodes/test_attacks.py::"
ROGUE = "test/nodes/test_attacks_rogue.py::"
#: Every attack: a pytest node id of test/nodes/test_attacks*.py.
ATTACKS = [OLD + t for t in (
    "test_a_second_commander_is_refused_and_the_tool_holds[during_run]",
    "test_a_second_commander_is_refused_and_the_tool_holds[after_abort]",
    "test_a_forged_clock_stops_the_run_with_the_reason[+30s]",
    "test_a_forged_clock_stops_the_run_with_the_reason[negative]",
    "test_a_frozen_monitor_holds_the_tool_within_the_budget",
    "test_a_second_planner_yields_and_a_start_is_served_once",
    "test_a_second_writer_of_the_tensions_aborts_with_its_name[lying]",
    "test_a_second_writer_of_the_tensions_aborts_with_its_name[flood]",
    "test_a_parameter_slip_in_one_node_is_refused_with_both_values",
    "test_a_spoofed_ready_heartbeat_does_not_open_the_interlock",
    "test_a_planner_killed_and_restarted_does_not_move_the_tool",
)] + [ROGUE + t for t in (
    "test_spoofed_acknowledgements_with_the_monitor_frozen_hold_the_tool[huge]",
    "test_spoofed_acknowledgements_with_the_monitor_frozen_hold_the_tool[mirror]",
    "test_a_rogue_parameter_change_of_the_running_monitor_is_refused[F_break]",
    "test_a_rogue_parameter_change_of_the_running_monitor_is_refused[ratio]",
    "test_malformed_announcements_and_messages_crash_no_node",
    "test_a_chain_from_the_domain_alone_does_not_tear",
    "test_a_frozen_monitor_of_a_managed_cell_with_a_forged_heartbeat_holds_the_tool",
)]
F_RE = re.compile(r"F_max ([0-9.]+) N \(threshold ([0-9.]+) N, allowed ([0-9.]+) N, "
                  r"F_break ([0-9.]+) N\)")
TB_RE = re.compile(r"process tracebacks: ([0-9]+)")
SEEN_RE = re.compile(r"frozen monitor seen by the simulator ([0-9.]+) s")


def one_run(attack: str, rtf: float, seed: int, domain: int, adaptive: bool = False) -> dict:
    env = dict(os.environ, RHEO_ATTACK_SEED=str(seed), RHEO_ATTACK_RTF=str(rtf),
               RHEO_ATTACK_ADAPTIVE="1" if adaptive else "0",
               ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-s", "-p", "no:cacheprovider",
                        attack], cwd=REPO, env=env, capture_output=True,
                       text=True)
    out = p.stdout + p.stderr
    m = F_RE.search(out)
    seen = SEEN_RE.search(out)
    res = {"attack": attack, "rtf": rtf, "seed": seed, "passed": p.returncode == 0,
           "wall_s": round(time.monotonic() - t0, 1),
           "F_max": float(m.group(1)) if m else None,
           "F_break": float(m.group(4)) if m else None,
           "traceback_in_nodes": bool(TB_RE.search(out)) and int(TB_RE.search(out).group(1)) > 0,
           "seen_s": float(seen.group(1)) if seen else None}
    res["tear"] = bool(m) and res["F_max"] >= res["F_break"]
    if p.returncode != 0:
        fail = [ln for ln in out.splitlines() if ln.startswith("E ")][:6]
        res["failure"] = "\n".join(fail)[-800:]
        res["output"] = out             # every node's log: a failure is read in full
    return res


def _commit() -> str:
    p = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
                       capture_output=True, text=True)
    return p.stdout.strip()


def summarise(results: list[dict], meta: dict, loads: list[float]) -> dict:
    """The campaign's figures per attack and rate (F_max median / max [N], the frozen
    monitor's detection [s]) from its runs (a finished or a cut-short campaign)."""
    summary = {}
    for attack in ATTACKS:
        for rtf in sorted({r["rtf"] for r in results}):
            rs = [r for r in results if r["attack"] == attack and r["rtf"] == rtf]
            if not rs:
                continue
            F = [r["F_max"] for r in rs if r["F_max"] is not None]
            seen = [r["seen_s"] for r in rs if r["seen_s"] is not None]
            summary[f"{attack} x{rtf:g}"] = {
                "runs": len(rs), "passed": sum(r["passed"] for r in rs),
                "tears": sum(r["tear"] for r in rs),
                "tracebacks": sum(r["traceback_in_nodes"] for r in rs),
                "F_max_median": statistics.median(F) if F else None,
                "F_max_max": max(F) if F else None,
                "seen_s_median": statistics.median(seen) if seen else None,
                "seen_s_max": max(seen) if seen else None,
                "failures": [r["failure"] for r in rs if not r["passed"]][:3]}
    return {"machine": f"{cpu_name()}, {os.cpu_count()} cores", **meta,
            "tears": sum(r["tear"] for r in results),
            "tracebacks": sum(r["traceback_in_nodes"] for r in results),
            "failed": sum(not r["passed"] for r in results), "runs": len(results),
            "load_average_median": round(statistics.median(loads), 2) if loads else None,
            "attacks": summary}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=50, help="runs per attack and rate")
    ap.add_argument("--rates", default="1,10", help="real-time factors (default 1,10)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("-k", default="",
                    help="only attacks whose name contains this (several: comma-separated)")
    ap.add_argument("--domain", type=int, default=None,
                    help="the ROS domain of a one-job campaign (default: one claimed per job)")
    ap.add_argument("--jobs", type=int, default=1, help="attacks run at once (default 1)")
    ap.add_argument("--adaptive", action="store_true",
                    help="the planner's closed loop on in every run (RHEO_ATTACK_ADAPTIVE=1)")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--resume", action="store_true",
                    help="go on with the cut-short campaign in --json: the same seed, runs, "
                         "rates, -k and commit; the runs it holds are not run again")
    ap.add_argument("--summarise", type=Path, nargs="+", default=None, metavar="JSON",
                    help="print the figures of campaigns already run (their --json files, "
                         "finished or cut short) and exit")
    args = ap.parse_args(argv)
    if args.summarise:
        results, loads, metas = [], [], []
        for path in args.summarise:
            try:
                d = json.loads(path.read_text())
            except (OSError, ValueError) as exc:
                ap.error(f"--summarise {path}: {exc}")
            results += d.get("runs", [])
            loads += d.get("loads", [])
            metas.append(d.get("meta") or d.get("report", {}).get("seed"))
        print(json.dumps(summarise(results, {"from": [str(p) for p in args.summarise],
                                             "meta": metas}, loads), indent=1))
        return 0
    rng = random.Random(args.seed)
    rates = [float(r) for r in args.rates.split(",")]
    wanted = [k for k in args.k.split(",") if k] or [""]
    todo = [(a, r) for a in ATTACKS if any(k in a for k in wanted)
            for r in rates for _ in range(args.runs)]
    rng.shuffle(todo)
    if args.jobs < 1:
        ap.error(f"--jobs {args.jobs}: expected a whole number >= 1")
    domains = [args.domain] if args.domain is not None and args.jobs == 1 else [
        claim_domain_id() for _ in range(args.jobs)]
    free = list(domains)
    seeds = [rng.randrange(2**31) for _ in todo]
    results, t0, loads = [], time.monotonic(), []
    meta = {"seed": args.seed, "runs_per_attack_and_rate": args.runs, "rates": rates,
            "jobs": args.jobs, "commit": _commit(), "adaptive": args.adaptive}
    if args.resume:
        if not args.json or not args.json.exists():
            ap.error(f"--resume: --json {args.json} is not a campaign's file")
        old = json.loads(args.json.read_text())
        old_meta = old.get("meta") or {}
        for key in ("seed", "runs_per_attack_and_rate", "rates", "commit", "adaptive"):
            if old_meta.get(key) != meta[key]:
                ap.error(f"--resume {args.json}: its {key} is {old_meta.get(key)!r}, this "
                         f"campaign's {meta[key]!r}; expected the same")
        if not old.get("partial"):
            ap.error(f"--resume {args.json}: that campaign finished; nothing to resume")
        results, loads = old["runs"], old["loads"]
        done = {(r["attack"], r["rtf"], r["seed"]) for r in results}
        if not done <= {(a, r, s) for (a, r), s in zip(todo, seeds)}:
            ap.error(f"--resume {args.json}: its runs are not this campaign's (another -k?)")
        keep = [i for i, (a, r) in enumerate(todo) if (a, r, seeds[i]) not in done]
        todo, seeds = [todo[i] for i in keep], [seeds[i] for i in keep]
        meta["resumed"] = old_meta.get("resumed", []) + [
            {"after_runs": len(results), "jobs": args.jobs}]
        meta["jobs"] = old_meta.get("jobs", args.jobs)

    logs = (args.json or Path("attack_campaign.json")).with_suffix(".logs")
    if args.json and not args.resume:
        # made before any run: a test checks that nothing appears in the source tree while
        # it runs (test/conftest.py), and a campaign run from a clone writes into it
        args.json.write_text(json.dumps({"partial": True, "meta": meta, "loads": [],
                                         "runs": []}, indent=1))
    logs.mkdir(exist_ok=True)
    # not empty from the start: git shows an untracked folder only once it holds a file,
    # and a failed run's log written while another run's test is running made that test
    # fail its clean-tree check (seed 4751: a run that passed counted as failed)
    (logs / "README").write_text(f"the output of each failed run of {logs.stem}.json\n")

    def job(i):
        domain = free.pop()
        try:
            return one_run(*todo[i], seeds[i], domain, args.adaptive)
        finally:
            free.append(domain)
    before = len(results)
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        for i, res in enumerate(pool.map(job, range(len(todo))), before + 1):
            results.append(res)
            loads.append(os.getloadavg()[0])
            if args.json:                   # what ran so far, should the campaign be cut short
                args.json.write_text(json.dumps({"partial": True, "meta": meta, "loads": loads,
                                                 "runs": results}, indent=1))
            if "output" in res:
                name = res["attack"].split("::")[-1][:60]
                (logs / f"{i:04d}_{name}_x{res['rtf']:g}.log").write_text(res.pop("output"))
            el = time.monotonic() - t0
            n = i - before
            print(f"\r[{i}/{before + len(todo)}] {el:.0f} s, "
                  f"ETA {el / n * (len(todo) - n):.0f} s, "
                  f"failed {sum(not r['passed'] for r in results)}, "
                  f"tears {sum(r['tear'] for r in results)}", end="", flush=True)
    print()
    report = summarise(results, meta | {"wall_s": round(time.monotonic() - t0, 1)}, loads)
    print(json.dumps(report, indent=1))
    if args.json:
        args.json.write_text(json.dumps({"report": report, "runs": results}, indent=1))
    return 0 if report["tears"] == 0 and report["tracebacks"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
