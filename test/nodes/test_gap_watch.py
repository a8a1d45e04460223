"""The gap_watch node as its own process over real DDS: a record fed in, rogue data beside it.

The test node plays a cell in namespace /gw: the plan's start on tool/planned_trajectory,
then a record the model makes of itself (the measurement model's noise) on tool/pose,
sheet/measured_profile and tool/wrench at about 10x real time, with rogue and malformed
messages among them: camera frames of 0, 1 and 20,000 points, NaN and infinite values,
poses, points and forces at 1e300, a
second publisher of tool/pose with zero, far-future and backward stamps, and a forged
/clock that jumps back and forth.  The node must keep running without a traceback, refuse
each bad sample with its reason (shaping/gap), keep stepping its model through the good
stream, and report on the absolute /diagnostics with the cell's hardware id.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import Pose, PoseArray, PoseStamped, WrenchStamped  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402

from rheo_shaping.nodes import messages as m  # noqa: E402
from rheo_shaping.nodes import topics as T  # noqa: E402
from rheo_shaping.planning.movement import synthesize_record  # noqa: E402
from rheo_shaping.units import NS  # noqa: E402

from _support.cells import base_cell, write_params  # noqa: E402
from _support.ros import Recorder, wait_for_subscribers  # noqa: E402

NSP = "/gw"
T0 = 1000.0          # s, stamp of the process start
FED_S = 30.0         # s of the record fed


def _params(tmp_path, cell):
    import yaml
    p = write_params(tmp_path / "cell.yaml", cell)
    data = yaml.safe_load(p.read_text())
    data["/**/gap_watch"] = {"ros__parameters": {
        "publish_period": 0.2, "diagnose_on_warn": False, "report_dir": str(tmp_path / "gw")}}
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


def test_gap_watch_survives_rogue_and_malformed_inputs(ros, procs, tmp_path):
    cell = base_cell()
    rec, _ = synthesize_record(cell, seed=3)
    gw = procs("gap_watch", "--ros-args", "--params-file", str(_params(tmp_path, cell)),
               "-r", f"__ns:={NSP}", "-p", "use_sim_time:=true", "-r", "/clock:=clock")
    node = ros.node("gw_feeder", namespace=NSP)
    pub = {name: node.create_publisher(t.type, t.name, t.qos) for name, t in (
        ("pose", T.TOOL_POSE), ("profile", T.MEASURED_PROFILE), ("wrench", T.TOOL_WRENCH),
        ("plan", T.PLANNED_TRAJECTORY))}
    # the rogue's own writers (a second publisher of each topic): the feeder's keep-last
    # history never overwrites a rogue sample before the node has read it
    rogue = ros.node("gw_rogue", namespace=NSP)
    rogue_pose = rogue.create_publisher(PoseStamped, T.TOOL_POSE.name, T.TOOL_POSE.qos)
    rogue_wrench = rogue.create_publisher(WrenchStamped, T.TOOL_WRENCH.name, T.TOOL_WRENCH.qos)
    rogue_profile = rogue.create_publisher(PoseArray, T.MEASURED_PROFILE.name,
                                           T.MEASURED_PROFILE.qos)
    clock = node.create_publisher(Clock, "clock", T.CLOCK.qos)
    rx = Recorder(node, {f"{NSP}/shaping/gap": String, "/diagnostics": DiagnosticArray})
    for p in (pub["pose"], pub["profile"], pub["wrench"], rogue_pose, rogue_wrench,
              rogue_profile, clock):
        wait_for_subscribers(ros, p, timeout=60.0)
    ros.spin_until(lambda: rx[f"{NSP}/shaping/gap"], 60.0, "the gap watch's first report")

    plan = JointTrajectory()
    plan.header.stamp = m.time_msg(int(T0 * NS))
    pub["plan"].publish(plan)

    def ns(t):
        return int(round((T0 + t) * NS))

    # the good stream, in stamp order, 0.1 s of process time per step at ~10x
    rogue_sent = 0
    ip = iw = ifr = 0
    t = 0.0
    step = 0
    while t <= FED_S:
        while ip < rec.pose_t.size and rec.pose_t[ip] <= t:
            pub["pose"].publish(m.pose_msg(rec.pose_xz[ip], ns(rec.pose_t[ip])))
            ip += 1
        while iw < rec.wrench_t.size and rec.wrench_t[iw] <= t:
            pub["wrench"].publish(m.wrench_msg(rec.wrench_xz[iw], ns(rec.wrench_t[iw])))
            iw += 1
        while ifr < rec.profile_t.size and rec.profile_t[ifr] <= t:
            pub["profile"].publish(m.profile_msg(rec.profiles[ifr], ns(rec.profile_t[ifr])))
            ifr += 1
        if step % 20 == 10:                         # every 2 s of process time: an attack
            k = (step // 20) % 6
            now = ns(t)
            if k == 0:                              # wrong lengths: 0, 1, 20,000 points
                for n in (0, 1, 20000):
                    msg = PoseArray(header=m.header(now))
                    msg.poses = [Pose() for _ in range(n)]
                    rogue_profile.publish(msg)
                    rogue_sent += 1
            elif k == 1:                            # NaN and infinity
                rogue_pose.publish(m.pose_msg((math.nan, 0.05), now + 1))
                rogue_wrench.publish(m.wrench_msg((math.inf, 0.0), now + 1))
                bad = m.profile_msg(np.array([[0.0, 0.01], [np.nan, 0.02], [0.0, 0.03]]), now)
                rogue_profile.publish(bad)
                rogue_sent += 3
            elif k == 2:                            # a second publisher, lying stamps
                for stamp in (0, ns(3600.0), ns(t - 5.0)):
                    rogue_pose.publish(m.pose_msg((0.5, -0.5), stamp))
                    rogue_sent += 1
            elif k == 3:                            # a forged clock, back and forth
                for c in (0, int(1e18), ns(t) - int(100 * NS), ns(t)):
                    clock.publish(m.clock_msg(c))
            elif k == 4:                            # a wrench from another clock
                w = WrenchStamped(header=m.header(ns(t) + int(1e6 * NS)))
                rogue_wrench.publish(w)
                rogue_sent += 1
            else:                                   # finite but out of any cell: 1e300
                rogue_pose.publish(m.pose_msg((1e300, 0.05), now + 1))
                rogue_wrench.publish(m.wrench_msg((0.0, 1e300), now + 1))
                far = m.profile_msg(np.array([[0.0, 0.01], [1e300, 0.02], [0.0, 0.03]]), now)
                rogue_profile.publish(far)
                rogue_sent += 3
        clock.publish(m.clock_msg(ns(t)))
        ros.spin_for(0.02)
        t += 0.1
        step += 1

    def last_gap():
        msgs = rx[f"{NSP}/shaping/gap"]
        return json.loads(msgs[-1].data) if msgs else {}

    # the model caught up with the stream (its time within a step and the pose window)
    def caught_up():
        return (last_gap().get("residuals") or {}).get("model_time_s", 0.0) >= FED_S - 1.0
    try:
        ros.spin_until(caught_up, 120.0, "the model to reach the fed stream's end")
    finally:
        (tmp_path / "last_gap.json").write_text(json.dumps(last_gap()))  # for a failure
    g = last_gap()
    refused = g["residuals"]["refused"]
    assert sum(refused.values()) >= 5, refused
    for reason in ("profile: fewer than 3 or more than max_points points",
                   "pose: non-finite position", "wrench: non-finite force",
                   "profile: non-finite point", "pose: stamp before the process start",
                   # one pose at 1e300 m sent the model into a loop it never left
                   "pose: farther than 10 m from the origin",
                   "profile: a point farther than 10 m from the origin",
                   "wrench: a force beyond 10000 N"):
        assert refused.get(reason, 0) >= 1, (reason, json.dumps(g))
    # the good stream was judged: profile residuals over the run
    assert g["residuals"]["run"]["profile_m"]["n"] > 1000
    # the node reports on the absolute /diagnostics with its cell's hardware id
    mine = [s for a in rx["/diagnostics"] for s in a.status
            if s.name == "gw/gap_watch: model gap"]
    assert mine and all(s.hardware_id == "shaping_cell/gw" for s in mine)
    assert "refused" in mine[-1].message
    # ~/diagnose answers (the run so far is written and handed to the worker process)
    cli = node.create_client(Trigger, f"{NSP}/gap_watch/diagnose")
    assert cli.wait_for_service(timeout_sec=30.0)
    fut = cli.call_async(Trigger.Request())
    ros.spin_until(fut.done, 30.0, "the ~/diagnose reply")
    assert fut.result().success, fut.result().message
    assert gw.proc.poll() is None, gw.text()
    assert gw.stop() == 0
    assert "Traceback" not in gw.text(), gw.text()
