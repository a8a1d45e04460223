"""A record played back onto the ROS graph, as ``ros2 bag play`` would (``rheo-shaping
replay``): each message at its stamp on the wall clock, with the QoS it was recorded with."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile

from ..records.qos import QosSpec, offered_qos
from ..units import NS
from . import messages as m
from . import topics as T
from .session import ros_session


def qos_profile(spec: QosSpec) -> QoSProfile:
    """The rclpy profile of a recorded :class:`~rheo_shaping.records.qos.QosSpec`."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, ReliabilityPolicy
    kw = {name: Duration(seconds=getattr(spec, name + "_s"))
          for name in ("deadline", "lifespan", "liveliness_lease_duration")
          if getattr(spec, name + "_s") is not None}
    return QoSProfile(depth=max(spec.depth, 1),
                      history=HistoryPolicy[spec.history.upper()],
                      reliability=ReliabilityPolicy[spec.reliability.upper()],
                      durability=DurabilityPolicy[spec.durability.upper()],
                      liveliness=LivelinessPolicy[spec.liveliness.upper()],
                      avoid_ros_namespace_conventions=spec.avoid_ros_namespace_conventions,
                      **kw)


def replay(record_dir: Path, *, namespace: str = "", rate: float = 1.0, clock: bool = True,
           progress: Callable[[str], None] | None = None,
           wait_for_subscribers: float = 0.0) -> dict:
    """Publish every message of a record's bag in stamp order, paced on the stamps.

    ``rate`` scales the pace (2: twice as fast); ``clock`` publishes ``clock`` (the
    root ``/clock`` in the root namespace) with each message's stamp first. Topics keep
    their names, moved into ``namespace``. Returns counts per topic.
    """
    from ..records.bag import read_record
    read_record(record_dir)                       # a valid record, or RecordError
    args = ["replay", "--ros-args"] + (["-r", f"__ns:={namespace}"] if namespace else [])
    with ros_session(args) as (context, executor, nodes):
        node = Node("replay", context=context)
        nodes.append(node)
        executor.add_node(node)
        return _play(node, executor, record_dir, rate, clock, wait_for_subscribers, progress)


def _play(node: Node, executor, record_dir: Path, rate: float, clock: bool,
          wait_for_subscribers: float, progress) -> dict:
    """The playback of :func:`replay` in its ROS session."""
    from rosbags.rosbag2 import Reader
    say = progress or (lambda _msg: None)
    counts: dict[str, int] = {}
    offered = offered_qos(record_dir)         # rosbag2's offered_qos_profiles
    with Reader(record_dir) as reader:
        pubs = {}
        for c in reader.connections:
            specs = offered.get(c.topic)
            if specs:                           # as recorded, like `ros2 bag play`
                qos = qos_profile(specs[0])
            else:
                topic = T.ALL.get(c.topic)
                # a deep history: a subscriber slower than the replay loses nothing
                qos = T.writer_qos(topic.qos if topic is not None else T.STATE_QOS)
            pubs[c.id] = node.create_publisher(get_message(c.msgtype), c.topic.lstrip("/"),
                                               qos)
        clock_pub = node.create_publisher(T.NAMESPACED_CLOCK.type, T.NAMESPACED_CLOCK.name,
                                          T.NAMESPACED_CLOCK.qos) if clock else None
        if wait_for_subscribers > 0:
            end = time.monotonic() + wait_for_subscribers
            while (time.monotonic() < end and not all(
                    p.get_subscription_count() > 0 for p in pubs.values())):
                executor.spin_once(timeout_sec=0.05)
        t_first = None
        wall0 = time.monotonic()
        for conn, stamp, raw in reader.messages():
            if t_first is None:
                t_first = stamp
                say(f"replay: {record_dir} from stamp {stamp / NS:.3f} s at x{rate:g}")
            due = wall0 + (stamp - t_first) / NS / rate
            while True:
                left = due - time.monotonic()
                if left <= 0:
                    break
                executor.spin_once(timeout_sec=min(left, 0.05))
            if clock_pub is not None:
                clock_pub.publish(m.clock_msg(stamp))
            pubs[conn.id].publish(bytes(raw))      # the bag's CDR, as recorded
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    wall = time.monotonic() - wall0 if counts else 0.0
    # reliable delivery of the last messages before this node leaves the graph
    for pub in pubs.values():
        pub.wait_for_all_acked(Duration(seconds=10.0))
    return {"record": str(record_dir), "messages": counts, "wall_time_s": wall}


def get_message(msgtype: str) -> type:
    """The rclpy message class of ``pkg/msg/Name``."""
    import importlib
    pkg, kind, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)
