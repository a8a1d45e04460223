"""A managed cell with its gap watch on a busy computer (issue 44): what ``ros2 launch
rheo_shaping cell.launch.py managed:=true gap_watch:=true`` starts (the four managed nodes
and the lifecycle manager with those ``node_names``), as processes over real DDS, under
``stress-ng --cpu 8`` (four runnable hogs per core on this 2-core machine).

What must hold every time, whatever the load does to the run: the manager's state is
whether the tool can move.  Every report of the simulator that the tool holds is followed
within a second by a manager that does not say ``active``; a manager that says ``active``
has every node active; the run's end (done, or a safe stop with its reason) is the same
on both sides.
"""
from __future__ import annotations

import json
import shutil
import subprocess

import pytest

pytest.importorskip("rclpy")

from rheo_shaping.nodes import topics as T  # noqa: E402
from rheo_shaping.units import NS  # noqa: E402

from _support.managed import (MANAGED, cell_recorder, managed_params,  # noqa: E402
                              manager_status)

_status, _params = manager_status, managed_params

NS_ = "/busy"
FOUR = ("simulator", "monitor", "gap_watch", "planner")
#: Longest time [s] from the simulator's report of a hold to the manager's: the latch rides
#: on the next heartbeat (0.1 s), the manager's check (0.05 s) and its status; one second
#: covers a process the hog stalls for half of it.
REPORT_LAG_S = 1.0


@pytest.fixture
def hog():
    exe = shutil.which("stress-ng")
    if exe is None:
        pytest.skip("stress-ng is not installed (apt install stress-ng): the busy cell needs it")
    p = subprocess.Popen([exe, "--cpu", "8", "--timeout", "600s", "--quiet"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    yield p
    p.terminate()
    p.wait(timeout=30)


def test_under_a_cpu_hog_the_managers_state_is_whether_the_tool_can_move(
        ros, procs, tmp_path, hog):
    params = _params(tmp_path)
    ros_args = ["--ros-args", "--params-file", str(params), "-r", f"__ns:={NS_}",
                *T.CLOCK_REMAP]
    cell = {node: procs(exe, *ros_args) for node, exe in MANAGED.items()}
    cell["gap_watch"] = procs("gap_watch_managed", *ros_args)
    cell["lifecycle_manager"] = procs("lifecycle_manager", *ros_args, "-p",
                                      "node_names:=[simulator,monitor,planner,gap_watch]")
    status_topic = f"{NS_}/lifecycle_manager/status"
    rec, planner_state = cell_recorder(ros, "busy_observer", NS_, depth=200)

    # the run's end: done, or the cell stopped (failed or held) with its reason
    ros.spin_until(lambda: planner_state() == "done"
                   or _status(rec, NS_).get("phase") in ("failed", "held"), 400.0,
                   "the busy cell's run to its end (done, or a safe stop)")
    ros.spin_for(2.0 * REPORT_LAG_S)       # the reports of the end on both sides
    statuses = [(info["source_timestamp"], json.loads(msg.data)) for msg, info
                in zip(rec[status_topic], rec.infos[status_topic])]
    for _, st in statuses:
        if st["phase"] == "active":
            assert st["nodes"] == {n: "active" for n in FOUR}, st

    def phase_at(t_ns: int) -> str:
        before = [st["phase"] for at, st in statuses if at <= t_ns]
        return before[-1] if before else ""
    name = f"{NS_.strip('/')}/simulator: sheet"
    holds = [(info["source_timestamp"], st.message) for msg, info
             in zip(rec[T.DIAGNOSTICS.name], rec.infos[T.DIAGNOSTICS.name])
             for st in msg.status if st.name == name and st.message.startswith("the tool holds")]
    late = [(t, why, phase_at(t + int(REPORT_LAG_S * NS))) for t, why in holds
            if phase_at(t + int(REPORT_LAG_S * NS)) == "active"]
    assert not late, f"the tool held while the manager said active: {late[:3]}"
    end = _status(rec, NS_)
    if planner_state() == "done":
        assert end["phase"] == "active" and not holds, (end, holds[:3])
    else:
        assert holds and end["phase"] in ("failed", "held") and end["reason"], (end, holds[:3])
    load = open("/proc/loadavg").read().split()[0]
    print(f"\nunder stress-ng --cpu 8 (load average {load}): the run ended "
          f"{'done' if planner_state() == 'done' else 'stopped: ' + end['reason']}; "
          f"{len(statuses)} manager statuses, {len(holds)} hold reports, none while active")
    for name_, p in cell.items():
        assert "Traceback" not in p.text(), f"{name_}:\n{p.text()[-3000:]}"
