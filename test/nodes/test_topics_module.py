"""rheo_shaping/nodes/topics.py is the one place of every topic's name, type and QoS:
each node's endpoints are exactly topics of that module, with its type and QoS (the
tension topics with the deadline of the node's settings), and they move with the
namespace."""
from __future__ import annotations

import pytest

pytest.importorskip("rclpy")

from rclpy.qos import DurabilityPolicy, ReliabilityPolicy  # noqa: E402

from rheo_shaping.nodes import topics as T  # noqa: E402

#: (node, direction) -> the topics it must have, by contract name
EXPECTED = {
    ("simulator", "pub"): {"/sheet/profile", "/sheet/measured_profile", "/sheet/tensions",
                           "/sheet/contact_tension", "/tool/pose", "/tool/wrench",
                           "/sheet/markers", "/diagnostics", "/clock", "/shaping/abort",
                           "/shaping/cell", "/shaping/commander", "/shaping/presence"},
    ("simulator", "sub"): {"/tool/command", "/shaping/checked", "/shaping/abort",
                           "/shaping/presence"},
    ("planner", "pub"): {"/tool/command", "/tool/planned_trajectory", "/shaping/planner_state",
                         "/shaping/presence"},
    ("planner", "sub"): {"/shaping/abort", "/shaping/ready", "/tool/pose", "/shaping/cell",
                         "/shaping/commander", "/shaping/presence"},
    ("monitor", "pub"): {"/shaping/abort", "/shaping/ready", "/shaping/checked", "/diagnostics",
                         "/shaping/presence"},
    ("monitor", "sub"): {"/sheet/tensions", "/sheet/contact_tension", "/sheet/profile",
                         "/tool/wrench", "/shaping/planner_state", "/shaping/cell",
                         "/shaping/presence"},
}


def _nodes(ros, namespace: str):
    from rclpy.parameter import Parameter
    from rheo_shaping.nodes.monitor import MonitorNode
    from rheo_shaping.nodes.planner import PlannerNode
    from rheo_shaping.nodes.simulator import SimulatorNode
    kw = dict(context=ros.context, namespace=namespace)
    fast = [Parameter("real_time_factor", value=10.0)]
    return {"simulator": ros.add(SimulatorNode(parameter_overrides=fast, **kw)),
            "planner": ros.add(PlannerNode(**kw)), "monitor": ros.add(MonitorNode(**kw))}


@pytest.mark.parametrize("namespace", ["/", "/cell7"])
def test_every_endpoint_is_a_topic_of_the_module(ros, namespace):
    nodes = _nodes(ros, namespace)
    # the planner creates /tool/command once it knows it is the only planner of its name
    ros.spin_until(lambda: nodes["planner"].pub_command is not None, 10.0, "/tool/command")
    for (name, direction), want in EXPECTED.items():
        node = nodes[name]
        endpoints = node.publishers if direction == "pub" else node.subscriptions
        got = {}
        for e in endpoints:
            if e.topic_name.endswith(("/parameter_events", "/rosout")) or \
                    e.topic_name == "/clock" and direction == "sub":
                continue                                     # rclpy's own
            if e.topic_name == T.TF_STATIC:                  # tf2's, checked below
                continue
            got[e.topic_name] = e
        want_names = {T.ALL[c].in_namespace(namespace) for c in want}
        assert set(got) == want_names, (name, direction, sorted(got))
        for contract in want:
            topic = T.ALL[contract]
            e = got[topic.in_namespace(namespace)]
            assert e.msg_type is topic.type, (name, contract)
            q = e.qos_profile
            assert q.reliability == ReliabilityPolicy.RELIABLE, (name, contract)
            assert q.durability == topic.qos.durability, (name, contract)
            # publishers of state keep a deeper history for slow readers (topics.writer_qos)
            writer = (direction == "pub" and name == "simulator"
                      and topic.qos.durability == DurabilityPolicy.VOLATILE)
            want_depth = T.writer_qos(topic.qos).depth if writer else topic.qos.depth
            assert q.depth == want_depth, (name, contract)
    assert (nodes["simulator"].pub_tensions.qos_profile.deadline.nanoseconds
            == int(nodes["simulator"].settings.offered_deadline * 1e9))
    sub = next(s for s in nodes["monitor"].subscriptions if s.topic_name.endswith("tensions"))
    assert sub.qos_profile.deadline.nanoseconds == int(
        nodes["monitor"].settings.max_data_age * 1e9)
    assert T.ABORT.qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    # the cake frame: absolute in any namespace, tf2_ros's static QoS (when tf2_msgs imports)
    tf = [e for e in nodes["simulator"].publishers if e.topic_name == T.TF_STATIC]
    if nodes["simulator"].pub_tf_static is not None:
        assert len(tf) == 1 and tf[0].qos_profile.depth == 1
        assert tf[0].qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert tf[0].qos_profile.reliability == ReliabilityPolicy.RELIABLE
    else:
        assert tf == []


def test_diagnostics_are_absolute_with_a_hardware_id_per_cell():
    """The diagnostic aggregator and rqt_robot_monitor read the absolute /diagnostics: every
    cell reports there, its namespace in the hardware id."""
    from rheo_shaping.nodes import messages as m
    assert T.DIAGNOSTICS.in_namespace("/cellA") == "/diagnostics" == T.DIAGNOSTICS.contract
    assert m.hardware_id("/cellA") == "shaping_cell/cellA" and m.hardware_id("/") == \
        "shaping_cell"
    msg = m.diagnostics_msg(1, "rheo_shaping/monitor", "OK", "ok", {}, m.hardware_id("/c2"))
    assert msg.status[0].hardware_id == "shaping_cell/c2"
