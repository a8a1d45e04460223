#!/usr/bin/env python3
"""Lag and CPU share of the gap_watch node in a running cell (issue 29), at x1 and x10.

Starts the cell as four processes over DDS (simulator, planner, monitor of
config/cell.yaml or --params, and gap_watch), at each real-time factor of --rates, runs
the movement to its end, and measures from this process:

* the gap watch's CPU share of one core: (user + system time of its process, /proc) over the
  wall time of the run (planner ``running`` to ``done``);
* its lag: every ``shaping/gap`` report (publish_period 0.5 s of wall time) says how long
  the newest sample waited in its queue (wall [s]) and how far the model's judged time trails
  the newest pose received (process time [s]; the model needs 0.2 s of poses beyond a time
  and steps only whole solver steps, up to solver.dt = 0.5 s); the table gives the median
  and the largest over the run, the process-time lag also in wall seconds (/ factor);
* its state at the end and the samples it dropped or refused (none expected).

x1 runs as ``launch/cell.launch.py use_sim_time:=false`` does (wall clock, no /clock); x10 with
the simulator as the clock.  The monitor runs with ``--max-data-age`` (2 s) so that the shared
machine's load does not abort the cell under the measurement.

    .venv/bin/python benchmarks/gapwatch_lag.py [--rates 1,10] [--params FILE] [--json]

ROS_DOMAIN_ID: one of this machine's free ids (test/_support/domains.py), discovery on
localhost.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import tempfile
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "test"))
from _support.domains import claim_domain_id  # noqa: E402  (stdlib only)

BIN = Path(sys.executable).parent
#: Where in the run (share of its wall time) --stall stops the gap watch.
STALL_AT = 0.3


def cpu_s(pid: int) -> float:
    """User + system CPU time [s] of process ``pid``."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(rate: float, params: str, timeout: float, max_data_age: float,
        stall: float = 0.0, model_file: str = "", verdict_wait: float = 0.0,
        want_verdicts: int = 1) -> dict:
    import rclpy
    from std_msgs.msg import String
    from rheo_shaping.nodes import topics as T
    env = dict(os.environ)
    # x1 as the launch file's use_sim_time:=false runs it: everything on the wall clock, no
    # /clock (lockstep waits only on simulated time); faster: the simulator is the clock
    sim = ["-p", f"real_time_factor:={rate}"]
    follow = ["-p", f"use_sim_time:={'false' if rate == 1 else 'true'}"]
    # the cell's own monitor at a data age the shared, loaded machine keeps (this measures the
    # gap watch, not the monitor: docs/safety.md has the monitor under load)
    monitor = follow + ["-p", f"max_data_age:={max_data_age}"]
    logdir = Path(tempfile.gettempdir()) / f"gapwatch_lag_x{rate:g}"
    logdir.mkdir(parents=True, exist_ok=True)
    procs = {}
    watch = follow + (["-p", f"model_file:={model_file}"] if model_file else [])
    for name, extra in (("gap_watch", watch), ("monitor", monitor), ("simulator", sim),
                        ("planner", follow)):
        log = open(logdir / f"{name}.log", "w")
        procs[name] = subprocess.Popen(
            [str(BIN / name), "--ros-args", "--params-file", params, *extra],
            stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env,
            start_new_session=True)
    rclpy.init()
    node = rclpy.create_node("gapwatch_lag")
    reports, states = [], []
    node.create_subscription(String, T.GAP.name, lambda m: reports.append(
        (time.monotonic(), json.loads(m.data))), 10)
    verdicts: list = []
    node.create_subscription(String, T.GAP_DIAGNOSIS.name, lambda m: verdicts.append(
        json.loads(m.data)), T.GAP_DIAGNOSIS.qos)
    node.create_subscription(String, T.PLANNER_STATE.name, lambda m: states.append(
        (time.monotonic(), m.data)), T.PLANNER_STATE.qos)
    pid = procs["gap_watch"].pid
    t_start = c_start = None
    t_end = c_end = None
    stalled = resumed = None
    from rheo_shaping.params.config import load_cell
    process = load_cell(params).movement.process_time
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
            state = states[-1][1] if states else ""
            if t_start is None and state == "running":
                t_start, c_start = time.monotonic(), cpu_s(pid)
            if stall and t_start is not None and stalled is None and \
                    time.monotonic() > t_start + STALL_AT * process / rate:
                os.kill(pid, signal.SIGSTOP)      # the whole gap_watch process stands still
                stalled = time.monotonic()
            if stalled is not None and resumed is None and time.monotonic() > stalled + stall:
                os.kill(pid, signal.SIGCONT)
                resumed = time.monotonic()
            if t_start is not None and state in ("done", "holding"):
                t_end, c_end = time.monotonic(), cpu_s(pid)
                break
        # the reports after the end: the model catches up with the last poses
        settle = time.monotonic() + 5.0
        while time.monotonic() < settle:
            rclpy.spin_once(node, timeout_sec=0.05)
        # a diagnosis the watch started: wait for its verdict
        settle = time.monotonic() + verdict_wait

        def pending() -> bool:
            done = [v for v in verdicts if v.get("state") == "done"]
            return bool(verdicts) and (verdicts[-1].get("state") != "done"
                                       or len(done) < want_verdicts)
        while pending() and time.monotonic() < settle:
            rclpy.spin_once(node, timeout_sec=0.05)
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(2)
        for p in procs.values():
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, 9)
        node.destroy_node()
        rclpy.shutdown()
    if t_end is None:
        return {"rate": rate, "error": f"the run did not finish within {timeout:g} s "
                f"(planner states: {[s for _, s in states][-5:]}); logs in {logdir}"}
    during = [r for t, r in reports if t_start <= t <= t_end and r.get("residuals")]
    import numpy as np
    wait = np.array([r["lag"]["last_s"] for r in during] or [0.0])
    oldest = np.array([r["lag"]["oldest_queued_s"] for r in during] or [0.0])
    trail = np.array([r["residuals"]["newest_pose_s"] - r["residuals"]["model_time_s"]
                      for r in during] or [0.0])
    last = reports[-1][1] if reports else {}
    tracebacks = [n for n in procs if "Traceback" in (logdir / f"{n}.log").read_text()]
    return {"rate": rate, "wall_s": t_end - t_start, "cpu_s": c_end - c_start,
            "cpu_share": (c_end - c_start) / (t_end - t_start),
            "queue_wait_s": {"median": float(np.median(wait)), "max": float(wait.max())},
            "oldest_queued_s_max": float(oldest.max()),
            "model_trail_process_s": {"median": float(np.median(trail)),
                                      "max": float(trail.max())},
            "model_trail_wall_s_max": float(trail.max()) / rate,
            "reports": len(during), "level_end": last.get("level"),
            "aborted": states[-1][1] == "holding",
            "warned": any(r.get("first_warn_s") is not None for r in during),
            "dropped": last.get("dropped"), "received": last.get("received"),
            "refused": (last.get("residuals") or {}).get("refused"),
            "tracebacks": tracebacks, "logs": str(logdir),
            "stall_s": stall, "caught_up_s": _caught_up(reports, resumed, rate),
            "first_warn_s": next((r.get("first_warn_s") for r in reversed(during)
                                  if r.get("first_warn_s") is not None), None),
            "verdict": verdicts[-1] if verdicts else None,
            "verdicts": [v for v in verdicts if v.get("state") == "done"]}


def _caught_up(reports, resumed, rate) -> float | None:
    """Wall seconds from the end of a stall until the model trails the newest pose by less
    than 3 s of process time again (None without a stall)."""
    if resumed is None:
        return None
    for t, r in reports:
        res = r.get("residuals") or {}
        if t > resumed and res and res["newest_pose_s"] - res["model_time_s"] < 3.0:
            return t - resumed
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", default="1,10", help="real-time factors (default 1,10)")
    ap.add_argument("--params", default=str(HERE.parent / "config" / "cell.yaml"))
    ap.add_argument("--timeout", type=float, default=0.0,
                    help="wall seconds per run (default: 3 x process time / rate + 120)")
    ap.add_argument("--max-data-age", type=float, default=2.0,
                    help="the monitor's max_data_age [s] in these runs (default 2)")
    ap.add_argument("--stall", type=float, default=0.0, metavar="S",
                    help="stop the gap_watch process (SIGSTOP) for S wall seconds at 30 %% of "
                         "the run, then let it go on (the cell must not notice)")
    ap.add_argument("--model-file", default="",
                    help="the gap watch's model cell (default: the cell of --params); with an "
                         "effect on in --params, the watch should WARN and diagnose")
    ap.add_argument("--verdict-wait", type=float, default=300.0,
                    help="wall seconds to wait after the run for a diagnosis the watch started")
    ap.add_argument("--verdicts", type=int, default=2,
                    help="verdicts to wait for when the watch warned (at WARN and at the end of "
                         "the run: 2)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if "ROS_DOMAIN_ID" not in os.environ:
        os.environ["ROS_DOMAIN_ID"] = str(claim_domain_id())
    from rheo_shaping.params.config import load_cell
    process = load_cell(a.params).movement.process_time
    out = []
    for rate in (float(r) for r in a.rates.split(",")):
        timeout = a.timeout or 3 * process / rate + 120
        out.append(run(rate, a.params, timeout, a.max_data_age, a.stall, a.model_file,
                       a.verdict_wait, a.verdicts))
        if not a.json:
            print(json.dumps(out[-1]), flush=True)
    if a.json:
        print(json.dumps(out))
        return
    print("| factor | run wall [s] | gap_watch CPU [s] | share of a core | queue wait median / "
          "max [s] | model behind newest pose, median / max [process s] | max [wall s] | "
          "state | dropped |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in out:
        if "error" in r:
            print(f"| x{r['rate']:g} | {r['error']} |")
            continue
        print(f"| x{r['rate']:g} | {r['wall_s']:.1f} | {r['cpu_s']:.2f} | {r['cpu_share']:.1%} "
              f"| {r['queue_wait_s']['median']:.3f} / {r['queue_wait_s']['max']:.3f} | "
              f"{r['model_trail_process_s']['median']:.2f} / "
              f"{r['model_trail_process_s']['max']:.2f} | {r['model_trail_wall_s_max']:.3f} | "
              f"{r['level_end']}{' (cell aborted)' if r['aborted'] else ''} | "
              f"{sum((r['dropped'] or {}).values())} |")


if __name__ == "__main__":
    main()
