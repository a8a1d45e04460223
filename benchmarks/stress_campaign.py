#!/usr/bin/env python3
"""The abort campaign under load and loss: does the monitor still stop every tear, and
only tears, on a busy computer and a lossy network?

Conditions (``--conditions``, any of):

* ``idle``: the campaign as ``abort_campaign.py`` runs it (three nodes in one process);
* ``cpu``: the same while a CPU hog keeps both cores busy (``stress-ng --cpu N`` when
  installed, else one Python busy loop per core), started and stopped by this script;
* ``loss``: the three nodes as three processes in a network namespace of their own
  (``ip netns``), DDS forced onto UDP (``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``; Fast DDS
  otherwise uses shared memory between processes on one host), and a random drop of
  ``--loss`` percent of the incoming UDP packets on the namespace's loopback (nftables,
  input hook, ``numgen random mod 100 < loss drop``). The namespace is made and removed
  here; its traffic never leaves it. Needs root, iproute2 and nftables. ``--jobs`` cases
  run at once, each cell in a ROS domain of its own.

In the process mode the figures come from the nodes' own logs (the simulator's F_max
over the whole process, which includes everything after an abort; the planner's stop
and rest times; the monitor's threshold and abort reason), never from a lossy observer;
the threshold crossing comes from the offline run of the same plan, which the closed
loop follows until the abort. A false abort under loss is reported with its reason,
so that aborts on data that really went stale can be told from wrong ones.

``--fault-tests`` runs the fault tests (``test/nodes/test_faults.py``: lost, late and
out-of-order samples, a node killed or restarted mid-run) under each condition instead,
once per condition, and reports pytest's counts.

Bounded: ``--runs`` per condition and seed, each run under a timeout; the hog and the
namespace are removed on exit, also on Ctrl-C.

    sudo .venv/bin/python benchmarks/stress_campaign.py [--runs 300] [--seeds 1,2]
        [--conditions idle,cpu,loss] [--loss 5] [--jobs 2] [--json] [--save FILE]
    sudo .venv/bin/python benchmarks/stress_campaign.py --fault-tests --conditions cpu,loss
    sudo .venv/bin/python benchmarks/stress_campaign.py --conditions loss --seeds 4742 \
        --cases 274 --repeat 8 [--end-order monitor,planner,simulator] --save FILE
"""
from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import json
import math
import os
import queue
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import abort_campaign as campaign  # noqa: E402
from _machine import cpu_name  # noqa: E402

BIN = Path(sys.executable).parent
NUM = r"([-+0-9.eE]+|inf|nan)"
#: set on Ctrl-C or SIGTERM: the running loss cases end their nodes at once
STOP = threading.Event()


# -- the CPU hog ----------------------------------------------------------------------------
@contextlib.contextmanager
def cpu_hog(cores: int):
    """Keep ``cores`` cores busy for the duration of the block."""
    if shutil.which("stress-ng"):
        procs = [subprocess.Popen(["stress-ng", "--cpu", str(cores), "--timeout", "86400s"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  start_new_session=True)]
    else:
        loop = "import time\nend = time.monotonic() + 86400\nwhile time.monotonic() < end: pass"
        procs = [subprocess.Popen([sys.executable, "-c", loop], start_new_session=True)
                 for _ in range(cores)]
    try:
        yield
    finally:
        for p in procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()


# -- the lossy namespace ------------------------------------------------------------------
def _sh(*cmd: str) -> None:
    subprocess.run(cmd, check=True, capture_output=True, text=True)


@contextlib.contextmanager
def lossy_namespace(loss_percent: int):
    """A network namespace with only a loopback that drops ``loss_percent`` % of incoming
    UDP packets; yields the command prefix that runs a program inside it."""
    name = f"rheo-loss-{os.getpid()}"
    _sh("ip", "netns", "add", name)
    try:
        inside = ["ip", "netns", "exec", name]
        _sh(*inside, "ip", "link", "set", "lo", "up")
        _sh(*inside, "nft", "add", "table", "inet", "rheo")
        _sh(*inside, "nft", "add", "chain", "inet", "rheo", "input",
            "{ type filter hook input priority 0; }")
        rule = ["meta", "l4proto", "udp"]
        if 0 < loss_percent < 100:
            rule += ["numgen", "random", "mod", "100", "lt", str(int(loss_percent))]
        if loss_percent > 0:
            _sh(*inside, "nft", "add", "rule", "inet", "rheo", "input", *rule, "drop")
        yield inside
    finally:
        subprocess.run(["ip", "netns", "del", name], capture_output=True)


# -- one case with three node processes ---------------------------------------------------
def run_case_processes(index: int, cell, prefix: list[str], domain: int, timeout: float,
                       end_order: tuple[str, ...] = ("planner", "monitor", "simulator"),
                       keep_logs: bool = False) -> dict:
    """Offline run, then the cell as three processes (inside ``prefix``); figures from logs.
    The nodes are interrupted in ``end_order`` at the case's end, each waited for; the logs
    are kept in the row on a false abort, or always with ``keep_logs``."""
    import yaml

    from rheo_shaping.params.config import dump_cell

    row, offline = campaign.offline_case(index, cell)
    if offline is None:
        return row
    rtf = campaign.RTF
    with tempfile.TemporaryDirectory(prefix="rheo-stress-") as tmp:
        params = Path(tmp) / "cell.yaml"
        data = yaml.safe_load(dump_cell(cell))
        data["/**/simulator"] = {"ros__parameters": {
            "real_time_factor": rtf, "step_period": 0.2 / rtf, "publish_period": 0.0,
            "publish_markers": False, "camera": False}}
        data["/**/planner"] = {"ros__parameters": {"use_sim_time": True, "autostart": True}}
        data["/**/monitor"] = {"ros__parameters": {"use_sim_time": True}}
        params.write_text(yaml.safe_dump(data, sort_keys=False))
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain),
                   ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                   FASTDDS_BUILTIN_TRANSPORTS="UDPv4", RCUTILS_LOGGING_BUFFERED_STREAM="0")
        logs = {n: Path(tmp) / f"{n}.log" for n in ("simulator", "planner", "monitor")}
        procs = {}
        for n, log in logs.items():
            procs[n] = subprocess.Popen([*prefix, str(BIN / n), "--ros-args", "--params-file",
                                         str(params)], stdout=open(log, "w"),
                                        stderr=subprocess.STDOUT, env=env,
                                        stdin=subprocess.DEVNULL,
                                        start_new_session=True)
        t0 = time.monotonic()
        done = False
        try:
            while time.monotonic() - t0 < timeout and not STOP.is_set():
                sim_log = logs["simulator"].read_text(errors="replace")
                if "process time" in sim_log and "reached: F_max" in sim_log:
                    done = True
                    break
                if any(p.poll() is not None for p in procs.values()):
                    break
                time.sleep(0.2)                  # polling the logs of processes we wait for
        finally:                                 # the nodes end with the case, also on a signal
            # the planner first, then the monitor, then the simulator, each waited for: a
            # monitor that left the graph while the planner still ran its plan would be a
            # stop the case itself caused (the plan can run past the process end)
            for n in end_order:
                p = procs[n]
                if p.poll() is None:
                    p.send_signal(signal.SIGINT)
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
                    p.wait()
        text = {n: log.read_text(errors="replace") for n, log in logs.items()}
    if not done:
        return {**row, "failed": "closed loop: no process end within the timeout",
                "log_tail": {n: t[-600:] for n, t in text.items()}}
    m = re.search(rf"reached: F_max = {NUM} N", text["simulator"])
    largest = float(m.group(1))
    m = re.search(rf"monitor up: abort at {NUM} N", text["monitor"])
    thr = float(m.group(1)) if m else math.nan
    start = re.search(rf"process starts at {NUM} s", text["simulator"])
    stop = re.search(rf"stopping from \w+ at {NUM} s, at rest in {NUM} s", text["planner"])
    aborted = "ABORT" in text["planner"] or "ABORT" in text["monitor"]
    reason = ""
    m = re.search(r"ABORT \((.*?)\)(?::|$)", text["planner"], re.M)
    if m:
        reason = m.group(1)
    abort_t = rest_t = None
    if stop and start:
        abort_t = float(stop.group(1)) - float(start.group(1))
        rest_t = abort_t + float(stop.group(2))
    largest_offline = offline.tension.max(axis=1)           # the plan's run without a monitor
    crossed = offline.t[largest_offline >= thr]
    t_cross = float(crossed[0]) if crossed.size else None
    row.update({
        "threshold_N": thr, "aborted": aborted, "aborted_before_threshold": False,
        "reason": reason, "largest_N": largest, "finished": True, "wall_time_s": None,
        "false_abort": bool(aborted and offline.F_max < thr),
        "missed": bool(offline.F_max >= thr and not aborted),
        **campaign.stop_intervals(t_cross, abort_t, rest_t),
        "max_tension_after_abort_N": largest if aborted else None,
    })
    row["tore"] = bool(largest >= cell.material.F_break)
    if row["false_abort"] or keep_logs:      # its whole output, to tell why
        row["logs"] = text
    return row


# -- main -----------------------------------------------------------------------------------
def run_condition(condition: str, seed: int, args) -> dict:
    import random

    from rheo_shaping.params.cell import CellParams
    rng = random.Random(seed)
    cells = [campaign.sample_cell(CellParams(), rng) for _ in range(args.runs)]
    order = list(range(len(cells)))
    if args.cases:                       # a rerun of chosen cases of the seed, --repeat times
        order = [int(i) for i in args.cases.split(",")] * args.repeat
    t0 = time.monotonic()
    done = 0

    def progress(k: int) -> None:
        """Runs finished so far, with the elapsed time and an ETA, on stderr."""
        nonlocal done
        done += k
        elapsed = time.monotonic() - t0
        eta = elapsed * (len(order) - done) / done
        print(f"  {condition} seed {seed}: {done}/{len(order)} runs, {elapsed / 60:.1f} min, "
              f"ETA {eta / 60:.1f} min", file=sys.stderr, flush=True)
    if condition in ("idle", "cpu"):
        from rheo_shaping.parallel import executor_from_spec, run_tasks
        shared = {"domain": args.domain, "trend": False}
        hog = cpu_hog(os.cpu_count() or 2) if condition == "cpu" else contextlib.nullcontext()
        with hog, executor_from_spec(None, jobs=args.jobs) as ex:
            rows = run_tasks(ex, campaign._campaign_task, shared, list(enumerate(cells)),
                             progress=progress, chunks_per_worker=8)
    else:
        end_order = tuple(args.end_order.split(","))
        rows = [None] * len(order)
        domains = queue.Queue()                   # one ROS domain per case running at once
        for k in range(max(args.jobs, 1)):
            domains.put(args.domain + k)

        def one(k: int) -> None:
            i = order[k]
            domain = domains.get()
            try:
                rows[k] = run_case_processes(i, cells[i], prefix, domain, args.timeout,
                                             end_order=end_order, keep_logs=bool(args.cases))
            finally:
                domains.put(domain)
            progress(1)
        with lossy_namespace(args.loss) as prefix, \
                concurrent.futures.ThreadPoolExecutor(max(args.jobs, 1)) as pool:
            futures = [pool.submit(one, k) for k in range(len(order))]
            try:
                for future in futures:
                    future.result()
            except BaseException:                 # Ctrl-C, SIGTERM: end the running cases
                STOP.set()
                pool.shutdown(wait=True, cancel_futures=True)
                raise
    summary = campaign.summarise(rows, time.monotonic() - t0)
    summary.update(condition=condition, seed=seed)
    if condition == "loss":
        summary["loss_percent"] = args.loss
        summary["false_abort_reasons"] = sorted({r.get("reason", "") for r in rows
                                                 if r.get("false_abort")})
    return {"summary": summary, "runs": rows}


def run_fault_tests(condition: str, args) -> dict:
    """``test/nodes/test_faults.py`` (pytest, the ROS stage) under ``condition``: under the
    hog, or inside the lossy namespace with DDS on UDPv4 (its node processes talk through the
    lossy loopback; its one-process cases pass samples within the process).  pytest's counts
    and the failed tests' names, from its JUnit XML."""
    import xml.etree.ElementTree as ET
    repo = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(repo))
    from dev import junit_counts     # the counts `dev.py test` reports
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="rheo-faults-") as tmp:
        junit = Path(tmp) / "junit.xml"
        cmd = [sys.executable, "-m", "pytest", "--stage=ros", "-q", "-p", "no:cacheprovider",
               f"--junitxml={junit}", str(repo / "test" / "nodes" / "test_faults.py")]
        env = dict(os.environ)
        where = contextlib.nullcontext([])
        if condition == "loss":
            env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
            where = lossy_namespace(args.loss)
        hog = cpu_hog(os.cpu_count() or 2) if condition == "cpu" else contextlib.nullcontext()
        with hog, where as prefix:       # bounded: 20 loss runs' worth of wall time
            proc = subprocess.run([*prefix, *cmd], env=env, cwd=repo, capture_output=True,
                                  text=True, timeout=args.timeout * 20)
        n = {"passed": 0, "failed": 0, "skipped": 0} | junit_counts(junit)
        names = [case.get("name") for case in ET.parse(junit).iter("testcase")
                 if case.find("failure") is not None or case.find("error") is not None
                 ] if junit.exists() else []
    summary = {"condition": condition, "fault_tests": sum(n.values()), **n,
               "failed_tests": names, "pytest_exit": proc.returncode,
               "wall_time_s": time.monotonic() - t0}
    if condition == "loss":
        summary["loss_percent"] = args.loss
    tail = proc.stdout[-3000:] if proc.returncode else ""
    return {"summary": summary, "output_tail": tail}


def provenance() -> dict:
    """The code and the machine a campaign ran on (its commit, cores, CPU, Python)."""
    repo = Path(__file__).resolve().parents[1]
    try:
        commit = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", "HEAD"],
                                capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    return {"commit": commit or None, "cpus": os.cpu_count(), "cpu": cpu_name(),
            "python": sys.version.split()[0], "load_average_end": os.getloadavg()}


def _terminate(signum, frame) -> None:  # noqa: ARG001 - a signal handler's signature
    raise SystemExit(128 + signum)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=300, help="runs per condition and seed")
    ap.add_argument("--seeds", default="1,2", help="comma-separated seeds (default 1,2)")
    ap.add_argument("--conditions", default="idle,cpu,loss",
                    help="comma-separated, any of idle, cpu, loss (default all three)")
    ap.add_argument("--loss", type=int, default=5, help="percent of UDP packets dropped (loss)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="cases run at once (default: the number of cores)")
    ap.add_argument("--domain", type=int, default=120, help="first ROS domain id to claim")
    ap.add_argument("--timeout", type=float, default=120.0, help="wall time per loss run [s]")
    ap.add_argument("--json", action="store_true",
                    help="print the summary as one JSON line at the end")
    ap.add_argument("--fault-tests", action="store_true",
                    help="run test/nodes/test_faults.py under each condition instead of the "
                         "campaign (once per condition; --runs and --seeds unused)")
    ap.add_argument("--cases", default="",
                    help="loss only: rerun these comma-separated case indices of the seed "
                         "(--repeat times each), keeping every node's log in the saved rows")
    ap.add_argument("--repeat", type=int, default=1, help="reruns of each of --cases")
    ap.add_argument("--end-order", default="planner,monitor,simulator",
                    help="loss only: the order the nodes are interrupted in at a case's end "
                         "(default planner,monitor,simulator)")
    ap.add_argument("--save", metavar="FILE",
                    help="write every run to FILE (JSON), after each condition and seed; "
                         "an existing FILE is never overwritten")
    args = ap.parse_args(argv)
    # SIGINT and SIGTERM end the campaign through its clean-up (the hog, the namespace, the
    # nodes), also when it was started in the background, where the shell ignores SIGINT
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _terminate)
    conditions = [c for c in args.conditions.split(",") if c]
    bad = [c for c in conditions if c not in ("idle", "cpu", "loss")]
    if bad or args.runs < 1 or not (0 <= args.loss <= 100):
        print(f"stress_campaign: error: conditions from idle,cpu,loss (got {bad}), --runs >= 1, "
              f"--loss in [0, 100]", file=sys.stderr)
        return 2
    if sorted(args.end_order.split(",")) != ["monitor", "planner", "simulator"]:
        print(f"stress_campaign: error: --end-order {args.end_order!r}: expected the three "
              f"names planner, monitor, simulator in some order", file=sys.stderr)
        return 2
    if args.cases and (conditions != ["loss"] or args.repeat < 1 or not all(
            c.isdigit() and int(c) < args.runs for c in args.cases.split(","))):
        print(f"stress_campaign: error: --cases {args.cases!r}: expected case indices below "
              f"--runs ({args.runs}), with --conditions loss and --repeat >= 1", file=sys.stderr)
        return 2
    if "loss" in conditions and (os.geteuid() != 0 or not shutil.which("nft")):
        print("stress_campaign: error: the loss condition needs root and nftables (nft)",
              file=sys.stderr)
        return 2
    if args.save and Path(args.save).exists():
        print(f"stress_campaign: error: {args.save} exists: not overwritten", file=sys.stderr)
        return 2
    seeds = [int(s) for s in args.seeds.split(",") if s]
    results = []
    if args.fault_tests:
        for c in conditions:
            print(f"  fault tests under {c} ...", file=sys.stderr, flush=True)
            results.append(run_fault_tests(c, args))
            results[-1]["summary"].update(provenance())
            print(json.dumps(results[-1]["summary"]) if args.json else results[-1]["summary"])
            if args.save:
                Path(args.save).write_text(json.dumps(results, indent=1))
        return 0 if all(r["summary"]["failed"] == 0 and r["summary"]["fault_tests"] > 0
                        for r in results) else 1
    for c in conditions:
        for s in seeds:
            results.append(run_condition(c, s, args))
            results[-1]["summary"].update(provenance())
            if args.save:          # after every condition and seed: an interrupt loses one
                Path(args.save).write_text(json.dumps(results, indent=1))
    keys = ("condition", "seed", "runs", "failed", "would_tear", "tears", "aborts", "false_aborts",
            "missed", "cross_to_rest_p99_s", "max_tension_after_abort_N", "wall_time_s")
    table = [{k: r["summary"].get(k) for k in keys} | (
        {"false_abort_reasons": r["summary"]["false_abort_reasons"]}
        if "false_abort_reasons" in r["summary"] else {}) for r in results]
    if args.json:
        print(json.dumps(table))
    else:
        for row in table:
            print(row)
    return 0 if all(r["summary"]["tears"] == 0 for r in results) else 1


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except KeyboardInterrupt:          # cleaned up on the way out: the hog, namespace, nodes
        print("stress_campaign: interrupted; nothing saved for the unfinished condition",
              file=sys.stderr)
        raise SystemExit(130)
