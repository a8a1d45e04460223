"""The shipped SROS2 policy (config/sros2/cell_policy.xml; docs/safety.md, "Access control")
against the cells as they run: every topic, service and client a node of the managed cell
(with the gap watch) or of the plain cell has is allowed to that node, in sros2's policy
format, and each stream a safety decision rests on is published by its owner alone
(docs/ros.md, "Who may write what").  To write the policy again from the running managed
cell: ``RHEO_WRITE_POLICY=FILE`` (or ``python -m rheo_shaping.nodes.policy`` beside a cell).
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from rheo_shaping.nodes import topics as T  # noqa: E402
from rheo_shaping.nodes.policy import (CELL_NODE_NAMES, ENCLAVE_ROOT, POLICY_VERSION,  # noqa: E402,E501
                                       allowed, dump, settled_policy)

from _support.cells import REPO  # noqa: E402
from _support.managed import MANAGED, cell_recorder, managed_params, manager_status  # noqa: E402,E501

POLICY = REPO / "config" / "sros2" / "cell_policy.xml"
#: the streams a safety decision rests on, and the one node that may publish each
OWNED = {"sheet/tensions": "simulator", "sheet/contact_tension": "simulator",
         "shaping/checked": "monitor", "shaping/ready": "monitor", "tool/command": "planner",
         "clock": "simulator"}
#: sros2's policy.xsd: the groups a profile holds, and the rules and element each takes
GROUPS = {"topics": ({"publish", "subscribe"}, "topic"),
          "services": ({"reply", "request"}, "service")}


def _live(ros, names) -> dict:
    graph = ros.node("policy_reader")

    def up() -> bool:
        return set(names) <= {n for n, ns in graph.get_node_names_and_namespaces() if ns == "/"}
    ros.spin_until(up, 120.0, f"the nodes {names} in the graph")
    return settled_policy(graph, {n: "/" for n in names}, lambda: ros.spin_for(0.1),
                          settle_s=3.0, timeout_s=60.0)


def _missing(live, shipped) -> dict:
    return {k: sorted(v - shipped.get(k, set())) for k, v in live.items()
            if v - shipped.get(k, set())}


def test_the_shipped_policy_has_sros2s_form_and_one_writer_per_owned_stream():
    root = ET.parse(POLICY).getroot()
    assert root.tag == "policy" and root.attrib == {"version": POLICY_VERSION}
    assert [c.tag for c in root] == ["enclaves"]
    enclaves = list(root[0])
    assert [e.attrib["path"] for e in enclaves] == [f"{ENCLAVE_ROOT}/{n}"
                                                    for n in CELL_NODE_NAMES]
    for enclave in enclaves:
        assert enclave.tag == "enclave" and [c.tag for c in enclave] == ["profiles"]
        (profile,) = list(enclave[0])
        assert profile.tag == "profile" and profile.attrib["ns"] == "/"
        assert enclave.attrib["path"].endswith("/" + profile.attrib["node"])
        for group in profile:
            rules, element = GROUPS[group.tag]
            assert set(group.attrib) <= rules and set(group.attrib.values()) == {"ALLOW"}
            assert len(group) >= 1 and {c.tag for c in group} == {element}
    rules = allowed(root)
    for topic, owner in OWNED.items():
        writers = {node for (node, rule), names in rules.items()
                   if rule == "publish" and topic in names}
        assert writers == {owner}, (topic, writers)
    # each node's heartbeat (~/heartbeat) is its own: no profile publishes another's
    for (node, rule), names in rules.items():
        if rule == "publish":
            assert not {n for n in names if n.endswith("/heartbeat") and not n.startswith("~")}


def test_the_managed_cell_does_nothing_the_shipped_policy_does_not_allow(
        ros, procs, tmp_path):
    params = managed_params(tmp_path)
    ros_args = ["--ros-args", "--params-file", str(params)]
    for exe in MANAGED.values():
        procs(exe, *ros_args)
    procs("gap_watch_managed", *ros_args)
    procs("lifecycle_manager", *ros_args, "-p",
          "node_names:=[simulator,monitor,gap_watch,planner]")
    rec, _ = cell_recorder(ros, "policy_observer", "")
    ros.spin_until(lambda: manager_status(rec, "").get("phase") == "active", 180.0,
                   "the managed cell active")
    policy = _live(ros, CELL_NODE_NAMES)
    if os.environ.get("RHEO_WRITE_POLICY"):
        Path(os.environ["RHEO_WRITE_POLICY"]).write_text(dump(policy))
    missing = _missing(allowed(policy), allowed(ET.parse(POLICY).getroot()))
    assert not missing, f"not in {POLICY.name}: {missing}"


def test_the_plain_cell_does_nothing_the_shipped_policy_does_not_allow(ros, procs, tmp_path):
    params = managed_params(tmp_path)
    for exe in ("simulator", "monitor", "planner"):
        procs(exe, "--ros-args", "--params-file", str(params))
    policy = _live(ros, ("simulator", "monitor", "planner"))
    missing = _missing(allowed(policy), allowed(ET.parse(POLICY).getroot()))
    assert not missing, f"not in {POLICY.name}: {missing}"
    assert T.TOOL_COMMAND.name.lstrip("/") in allowed(policy)[("planner", "publish")]
