#!/usr/bin/env python3
"""Signals during a node's start-up: each node executable is started and sent SIGINT
(or SIGTERM) after a random delay within its start-up; it must end with exit code 0 and
print no traceback, every time.

The delays are uniform in [0, --window] s (default: the node's measured start-up time
plus 0.5 s, so the signal lands in the imports, the kernel's loading, rclpy.init, the
node's construction and the first spins). Each run is bounded (--exit-timeout), the
whole campaign by --runs; ROS traffic stays on this machine (its own ROS domain,
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST).

    .venv/bin/python benchmarks/early_signals.py [--runs 50] [--nodes simulator,planner,monitor]
        [--seed 1] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

BIN = Path(sys.executable).parent
READY = {"simulator": "simulator up", "planner": "state:", "monitor": "monitor up"}


def _default_signals() -> None:
    """The node starts with SIGINT and SIGTERM at their defaults, as from a terminal or
    ros2 launch, whatever this script inherited (a background job of a script ignores
    SIGINT, and a signal that comes while it is ignored is rightly dropped)."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_DFL)


def start(exe: str, env: dict) -> subprocess.Popen:
    return subprocess.Popen([str(BIN / exe)], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=env, start_new_session=True,
                            preexec_fn=_default_signals)


def startup_time(exe: str, env: dict, timeout: float = 120.0) -> float:
    """Seconds until the node logs that it is up (its first line after construction)."""
    t0 = time.monotonic()
    p = start(exe, env)
    try:
        for line in p.stdout:
            if READY[exe] in line:
                return time.monotonic() - t0
            if time.monotonic() - t0 > timeout:
                break
        return time.monotonic() - t0
    finally:
        p.send_signal(signal.SIGINT)
        try:
            p.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()


def one_run(exe: str, delay: float, sig: int, env: dict, exit_timeout: float) -> dict:
    p = start(exe, env)
    time.sleep(delay)                     # the point of the test: a signal at a random moment
    p.send_signal(sig)
    try:
        out, _ = p.communicate(timeout=exit_timeout)
        rc = p.returncode
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, _ = p.communicate()
        rc = "timeout"
    return {"node": exe, "delay_s": round(delay, 3), "signal": signal.Signals(sig).name,
            "rc": rc, "traceback": "Traceback" in out,
            "ok": rc == 0 and "Traceback" not in out,
            "tail": out[-1500:] if (rc != 0 or "Traceback" in out) else ""}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=50, help="signals per node (default 50)")
    ap.add_argument("--nodes", default="simulator,planner,monitor")
    ap.add_argument("--window", type=float, default=None,
                    help="largest delay [s] (default: measured start-up + 0.5 s)")
    ap.add_argument("--exit-timeout", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    nodes = [n for n in args.nodes.split(",") if n]
    if args.runs < 1 or any(n not in READY for n in nodes):
        print(
            f"early_signals: error: --runs >= 1 and --nodes from {sorted(READY)}", file=sys.stderr)
        return 2
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    rng = random.Random(args.seed)
    rows, windows = [], {}
    t0 = time.monotonic()
    for exe in nodes:
        windows[exe] = args.window if args.window is not None else startup_time(exe, env) + 0.5
        for _ in range(args.runs):
            sig = rng.choice([signal.SIGINT, signal.SIGINT, signal.SIGTERM])
            rows.append(one_run(exe, rng.uniform(0.0, windows[exe]), sig, env, args.exit_timeout))
    summary = {"runs": len(rows), "ok": sum(r["ok"] for r in rows),
               "tracebacks": sum(r["traceback"] for r in rows),
               "nonzero_exits": sum(r["rc"] != 0 for r in rows),
               "windows_s": windows, "per_node": {n: sum(r["ok"] for r in rows if r["node"] == n)
                                                  for n in nodes},
               "failures": [r for r in rows if not r["ok"]][:10],
               "wall_time_s": time.monotonic() - t0}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"{summary['ok']} of {summary['runs']} signals ended the node with exit 0 and no "
              f"traceback; tracebacks {summary['tracebacks']}, non-zero exits "
              f"{summary['nonzero_exits']}")
        for n in nodes:
            print(f"  {n:9s} window {windows[n]:.2f} s: {summary['per_node'][n]}/{args.runs} ok")
        for r in summary["failures"]:
            print("  FAIL", r)
    return 0 if summary["ok"] == summary["runs"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
