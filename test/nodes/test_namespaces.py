"""Two cells in two namespaces in one ROS domain, side by side (issue 15, relative names).

Cell A (``/cellA``) runs the default cell on 31 masses to the end; cell B
(``/cellB``) runs a 15-mass sheet with a monitor set to abort (abort_ratio 0.5,
F_abort 0.52 N below movement 4's F_max 0.65 N).  Both run at once as
``rheo-shaping cell --namespace NS --clock-topic clock`` processes, each with its own
simulated clock in its namespace (the default, the absolute ``/clock``, is one cell's).
Senders are told apart by the graph (the GID and node of every publisher on each topic)
and by content (the number of poses is the cell's ``sheet.n_masses``; only B aborts),
never by counting messages in flight.
"""
from __future__ import annotations

import json
import os
import subprocess

import pytest

pytest.importorskip("rclpy")

from rheo_shaping.nodes import topics as T  # noqa: E402

from _support.ros import BIN, Recorder  # noqa: E402

CELLS = {"/cellA": 31, "/cellB": 15}
#: Two cells share the busy machine: 10x real time keeps each step well inside the
#: monitors' max_data_age (0.5 s of wall time), so neither aborts for stale data.
REAL_TIME_FACTOR = 10.0
START_TIMEOUT_S = 120.0     # both processes settle their sheets and plan on a busy machine
RUN_TIMEOUT_S = 240.0


def _params(tmp_path, ns: str) -> str:
    path = tmp_path / f"{ns.strip('/')}.yaml"
    text = f"/**:\n  ros__parameters:\n    sheet:\n      n_masses: {CELLS[ns]}\n"
    if ns == "/cellB":
        text += "/**/monitor:\n  ros__parameters:\n    abort_ratio: 0.5\n"
    path.write_text(text)
    return str(path)


def _publishers(node, name: str) -> list:
    return node.get_publishers_info_by_topic(name)


def test_two_namespaced_cells_share_a_domain_and_keep_their_own_topics(ros, tmp_path):
    procs = {}
    logs = {}
    for ns in CELLS:
        logs[ns] = open(tmp_path / f"{ns.strip('/')}.log", "w")
        procs[ns] = subprocess.Popen(
            [str(BIN / "rheo-shaping"), "cell", "--namespace", ns, "--clock-topic", "clock",
             "--json", "--params",
             _params(tmp_path, ns), "--timeout", str(RUN_TIMEOUT_S),
             "--real-time-factor", str(REAL_TIME_FACTOR)],
            stdout=subprocess.PIPE, stderr=logs[ns], text=True, env=dict(os.environ),
            start_new_session=True)
    try:
        node = ros.node("namespace_observer")
        topics = {}
        for ns in CELLS:
            topics[T.PROFILE.in_namespace(ns)] = T.PROFILE.type
            topics[T.ABORT.in_namespace(ns)] = (T.ABORT.type, True)
            topics[T.PLANNER_STATE.in_namespace(ns)] = (T.PLANNER_STATE.type, True)
        topics[T.PROFILE.contract] = T.PROFILE.type
        rec = Recorder(node, topics)
        profile = {ns: T.PROFILE.in_namespace(ns) for ns in CELLS}

        # Both cells publish their sheets at the same time.
        ros.spin_until(lambda: all(rec[profile[ns]] for ns in CELLS), START_TIMEOUT_S,
                       "a profile from both cells",
                       every=lambda: [pytest.fail(f"{ns} exited early: {p.poll()}")
                                      for ns, p in procs.items() if p.poll() is not None])
        assert all(p.poll() is None for p in procs.values()), "both cells run side by side"

        # The graph: each namespaced topic has exactly one publisher, the simulator (or
        # monitor) of its own namespace; nothing is published on the root contract name.
        gids = {}
        for ns in CELLS:
            # (/shaping/abort: the monitor, and the simulator, which reports its own stops)
            for topic, node_names in ((T.PROFILE, ["simulator"]),
                                      (T.ABORT, ["monitor", "simulator"]),
                                      (T.TENSIONS, ["simulator"]), (T.TOOL_COMMAND, ["planner"]),
                                      (T.NAMESPACED_CLOCK, ["simulator"])):
                name = topic.in_namespace(ns)
                want = sorted((ns, n) for n in node_names)
                # discovery first reports an endpoint, then (a little later) its node's name
                ros.spin_until(lambda: sorted((i.node_namespace, i.node_name)
                                              for i in _publishers(node, name)) == want, 30.0,
                               f"the publishers {want} on {name}")
                infos = sorted(_publishers(node, name), key=lambda i: i.node_name)
                gids[(ns, topic.name)] = bytes(infos[0].endpoint_gid)
        assert gids[("/cellA", T.PROFILE.name)] != gids[("/cellB", T.PROFILE.name)]
        assert gids[("/cellA", T.ABORT.name)] != gids[("/cellB", T.ABORT.name)]
        assert _publishers(node, T.PROFILE.contract) == []
        assert _publishers(node, T.ABORT.contract) == []
        assert _publishers(node, "/clock") == []

        # Run both to the end (their own verdicts, over their own topics).
        results = {}
        for ns, p in procs.items():
            while p.poll() is None:
                ros.spin_for(0.2)
            results[ns] = json.loads(p.stdout.read().strip().splitlines()[-1])
        assert procs["/cellA"].returncode == 0, results["/cellA"]["abort_reason"]
        assert procs["/cellB"].returncode == 3, results["/cellB"]
        assert not results["/cellA"]["aborted"] and results["/cellA"]["finished"]
        assert results["/cellB"]["aborted"]

        # Content: every profile on /NS/sheet/profile has that cell's number of masses.
        for ns, n in CELLS.items():
            sizes = {len(msg.poses) for msg in rec[profile[ns]]}
            assert sizes == {n}, (ns, sizes)
        assert rec[T.PROFILE.contract] == []
        # Only B's monitor aborted, and its reason is on B's topic (latched: a late
        # subscriber gets it); A's abort topic carries nothing, A's run says not aborted.
        abort_b = rec[T.ABORT.in_namespace("/cellB")]
        assert abort_b and abort_b[-1].data in results["/cellB"]["abort_reason"]
        assert rec[T.ABORT.in_namespace("/cellA")] == []
        assert results["/cellA"]["planner_state"] == "done"
        assert results["/cellB"]["planner_state"] == "holding"
        # The latched planner state each namespace ends with is its own planner's.
        for ns in CELLS:
            last = rec[T.PLANNER_STATE.in_namespace(ns)]
            assert last and last[-1].data == results[ns]["planner_state"], ns
    finally:
        for ns, p in procs.items():
            if p.poll() is None:
                p.kill()
                p.wait()
            logs[ns].close()
