"""The QoS a record says its topics were offered with (records/qos.py, ROS-free) is the
QoS rheo_shaping/nodes/topics.py gives the simulator's publishers of those topics."""
from __future__ import annotations

import pytest

pytest.importorskip("rclpy")

from rclpy.duration import Duration  # noqa: E402

from rheo_shaping.nodes import topics as T  # noqa: E402
from rheo_shaping.records import qos as Q  # noqa: E402
from rheo_shaping.records.bag import TYPES  # noqa: E402


def _seconds(d: Duration) -> float | None:
    """rclpy's unset duration (0 ns) is the spec's None."""
    return None if d.nanoseconds == 0 else d.nanoseconds / 1e9


def _spec(profile) -> Q.QosSpec:
    """An rclpy QoSProfile in the records' ROS-free words."""
    return Q.QosSpec(depth=profile.depth, history=profile.history.name.lower(),
                     reliability=profile.reliability.name.lower(),
                     durability=profile.durability.name.lower(),
                     deadline_s=_seconds(profile.deadline),
                     lifespan_s=_seconds(profile.lifespan),
                     liveliness=profile.liveliness.name.lower(),
                     liveliness_lease_duration_s=_seconds(profile.liveliness_lease_duration),
                     avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions)


def test_the_recorded_topics_are_topics_of_the_cell_with_their_types():
    assert set(Q.RECORDED_QOS) == set(TYPES)
    for name, msgtype in TYPES.items():
        topic = T.ALL[name]
        assert f"{topic.type.__module__.split('.')[0]}/msg/{topic.type.__name__}" == msgtype


@pytest.mark.parametrize("name", sorted(TYPES))
def test_recorded_qos_is_what_the_simulator_offers(name):
    """The simulator publishes each state topic with ``writer_qos(topic.qos)``
    (nodes/simulator.py ``_publisher``)."""
    assert Q.RECORDED_QOS[name] == (_spec(T.writer_qos(T.ALL[name].qos)),)
    assert Q.WRITER_DEPTH == T.WRITER_DEPTH


def test_the_spec_round_trips_through_rosbags_with_a_deadline():
    spec = _spec(T.writer_qos(T.tension_qos(0.25)))
    assert spec.deadline_s == 0.25
    assert Q.from_rosbags(Q.to_rosbags(spec)) == spec


def test_replay_publishes_with_the_recorded_profiles():
    """`replay` builds each publisher from the record's offered_qos_profiles (like
    `ros2 bag play`): the profile it builds says what the record says."""
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

    from rheo_shaping.nodes.replay import qos_profile
    from rheo_shaping.records.qos import QosSpec
    q = qos_profile(QosSpec(depth=7, reliability="best_effort", durability="transient_local",
                            deadline_s=0.25))
    assert q.depth == 7 and q.reliability == ReliabilityPolicy.BEST_EFFORT
    assert q.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert q.deadline.nanoseconds == 250_000_000
