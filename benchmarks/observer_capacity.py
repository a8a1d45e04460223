#!/usr/bin/env python3
"""How many messages per second one Python observer takes without loss (the e2e tests' rig).

A publisher process sends two reliable streams (``PoseStamped`` and a 31-pose
``PoseArray``, as /tool/command and /sheet/profile) at a given rate each for a
given time; this process records them with the tests' own ``Recorder``
(``test/_support/ros.py``: a single-threaded executor, 1000-deep reliable
readers) and counts the messages lost, by gaps in the publisher's sequence
numbers.  Run it idle and with a CPU hog (``stress-ng --cpu 2``) to choose the
real-time factors of the e2e tests (``test/_support/rigs.py``).

    .venv/bin/python benchmarks/observer_capacity.py [--rates 300,600,1000] [--seconds 10]
        [--json]

Measured 2026-12-03 on the project's 2-core machine, 10 s per rate (two streams, so the
total is twice the rate): idle, 0 lost at 300/s and 600/s, about 1 % at 1000/s; with
``stress-ng --cpu 2``, 0 lost at 150/s and 300/s, 31 % at 600/s.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "test"))
from _support.domains import claim_domain_id  # noqa: E402  (stdlib only)

PUBLISHER = r"""
import sys, time, rclpy
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from rclpy.qos import QoSProfile, ReliabilityPolicy
rate, seconds = float(sys.argv[1]), float(sys.argv[2])
rclpy.init()
node = rclpy.create_node("capacity_publisher")
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
pubs = [node.create_publisher(PoseStamped, "/capacity/command", qos),
        node.create_publisher(PoseArray, "/capacity/profile", qos)]
deadline = time.monotonic() + 60.0
while any(p.get_subscription_count() < 1 for p in pubs):
    if time.monotonic() > deadline:
        sys.exit("no observer matched within 60 s")
    rclpy.spin_once(node, timeout_sec=0.05)
time.sleep(1.0)                 # the observer's matching of us, too
profile = PoseArray()
profile.poses = [Pose() for _ in range(31)]
k, t0 = 0, time.monotonic()
while time.monotonic() - t0 < seconds:
    due = int((time.monotonic() - t0) * rate)
    while k < due:
        command = PoseStamped()
        command.header.stamp.sec = k
        profile.header.stamp.sec = k
        pubs[0].publish(command)
        pubs[1].publish(profile)
        k += 1
    time.sleep(0.002)
print(k, flush=True)
time.sleep(3.0)                 # serve the reliable resends before leaving
node.destroy_node()
rclpy.shutdown()
"""


def measure(rate: float, seconds: float) -> dict:
    from geometry_msgs.msg import PoseArray, PoseStamped

    from _support.ros import Recorder, Ros
    ros = Ros()
    try:
        rec = Recorder(ros.node("capacity_observer"),
                       {"/capacity/command": PoseStamped, "/capacity/profile": PoseArray})
        pub = subprocess.Popen([sys.executable, "-c", PUBLISHER, str(rate), str(seconds)],
                               stdout=subprocess.PIPE, text=True)
        while pub.poll() is None:
            ros.executor.spin_once(timeout_sec=0.01)
        ros.spin_for(1.0)
        sent = int(pub.stdout.read().strip() or 0)
        got = {t: len(rec[t]) for t in rec.msgs}
        lost = {t: sent - n for t, n in got.items()}
        return {"rate_per_stream": rate, "sent_per_stream": sent, "received": got,
                "lost": lost, "lost_by_sequence_gaps": {t: rec.lost(t) for t in rec.msgs}}
    finally:
        ros.close()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rates", default="300,600,1000",
                    help="messages/s per stream (two streams), comma-separated")
    ap.add_argument("--seconds", type=float, default=10.0, help="time per rate [s]")
    ap.add_argument("--json", action="store_true", help="print one JSON object at the end")
    a = ap.parse_args(argv)
    try:
        rates = [float(r) for r in a.rates.split(",")]
    except ValueError:
        ap.error(f"--rates: {a.rates!r} is not a comma-separated list of numbers")
    if any(r <= 0 for r in rates) or a.seconds <= 0:
        ap.error("--rates and --seconds must be positive")
    # this process and its publisher only: a domain of their own, traffic on this machine
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("ROS_DOMAIN_ID", str(claim_domain_id()))
    with open("/proc/loadavg") as f:
        load = f.read().split()[:3]
    if not a.json:
        print(f"load average at start: {load}")
    results = []
    for rate in rates:
        t0 = time.monotonic()
        r = measure(rate, a.seconds)
        results.append(r)
        total = sum(r["lost"].values())
        share = 100 * total / max(2 * r["sent_per_stream"], 1)
        if not a.json:
            print(f"{rate:6g}/s per stream ({2 * rate:g}/s in all): sent "
                  f"{r['sent_per_stream']} per stream, lost {total} ({share:.1f} %) {r['lost']} "
                  f"[{time.monotonic() - t0:.0f} s]", flush=True)
    if a.json:
        print(json.dumps({"load_average": load, "seconds": a.seconds, "results": results}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
