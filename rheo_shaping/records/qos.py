"""The QoS each recorded topic is published with, without ROS (docs/records.md).

A rosbag2 record keeps, per topic, the QoS profiles its publishers offered
(metadata.yaml ``offered_qos_profiles``); ``ros2 bag play`` and ``rheo-shaping
replay`` publish with them, so a late-joining or deadline-checking subscriber sees
what it saw live.  The records are core (no rclpy), so the profiles are written
here as :class:`QosSpec`, in rosbag2's own words; test/nodes/test_recorded_qos.py
checks that they are the profiles rheo_shaping/nodes/topics.py gives the
simulator's publishers (``writer_qos(topic.qos)``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..units import NS

#: A publisher's history of state samples (nodes/topics.py WRITER_DEPTH).
WRITER_DEPTH = 100

HISTORIES = ("system_default", "keep_last", "keep_all")
RELIABILITIES = ("system_default", "reliable", "best_effort", "best_available")
DURABILITIES = ("system_default", "transient_local", "volatile", "best_available")
LIVELINESSES = ("system_default", "automatic", "manual_by_topic", "best_available")

#: rosbag2's "infinite" duration (RMW_DURATION_INFINITE as sec, nsec), what a record made
#: by ``ros2 bag record`` holds for a deadline, lifespan or lease that was not set.
INFINITE = (9223372036, 854775807)


@dataclass(frozen=True)
class QosSpec:
    """One QoS profile: the policies rosbag2 writes, named as in metadata.yaml version 9.

    Durations [s]; ``None``: not set (the RMW default, no deadline / lifespan / lease).
    The defaults are rclpy's ``QoSProfile(depth=...)``.
    """

    depth: int
    history: str = "keep_last"
    reliability: str = "reliable"
    durability: str = "volatile"
    deadline_s: float | None = None
    lifespan_s: float | None = None
    liveliness: str = "system_default"
    liveliness_lease_duration_s: float | None = None
    avoid_ros_namespace_conventions: bool = False

    def __post_init__(self):
        for name, allowed in (("history", HISTORIES), ("reliability", RELIABILITIES),
                              ("durability", DURABILITIES), ("liveliness", LIVELINESSES)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"QoS {name} = {getattr(self, name)!r}: expected one of "
                                 + ", ".join(allowed))
        if not (isinstance(self.depth, int) and self.depth >= 0):
            raise ValueError(f"QoS depth = {self.depth!r}: expected a whole number >= 0")


#: The profile each recorded topic is offered with: the simulator's state publishers
#: (reliable, volatile, keep the last WRITER_DEPTH samples).
STATE_OFFERED = QosSpec(depth=WRITER_DEPTH)
#: Recorded topic (root-namespace name) -> the QoS profiles offered on it.
RECORDED_QOS: dict[str, tuple[QosSpec, ...]] = {
    "/tool/pose": (STATE_OFFERED,),
    "/sheet/measured_profile": (STATE_OFFERED,),
    "/tool/wrench": (STATE_OFFERED,),
}


def _time(seconds: float | None):
    from rosbags.interfaces import QosTime
    if seconds is None:
        return QosTime(0, 0)
    ns = int(round(seconds * NS))
    return QosTime(ns // NS, ns % NS)


def _seconds(t) -> float | None:
    if (t.sec, t.nsec) in ((0, 0), INFINITE):
        return None
    return t.sec + t.nsec / NS


def to_rosbags(spec: QosSpec):
    """``spec`` as the ``rosbags`` Qos that its writer dumps into metadata.yaml."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability)
    return Qos(history=QosHistory[spec.history.upper()], depth=spec.depth,
               reliability=QosReliability[spec.reliability.upper()],
               durability=QosDurability[spec.durability.upper()],
               deadline=_time(spec.deadline_s), lifespan=_time(spec.lifespan_s),
               liveliness=QosLiveliness[spec.liveliness.upper()],
               liveliness_lease_duration=_time(spec.liveliness_lease_duration_s),
               avoid_ros_namespace_conventions=bool(spec.avoid_ros_namespace_conventions))


def from_rosbags(qos) -> QosSpec | None:
    """A ``rosbags`` Qos read from a record as a :class:`QosSpec`; None for a policy
    rosbag2 could not know (``unknown``: ``ros2 bag record`` of a publisher the graph
    reports only in part), where a replay keeps its own default."""
    names = {f: getattr(qos, f).name.lower()
             for f in ("history", "reliability", "durability", "liveliness")}
    if "unknown" in names.values():
        return None
    return QosSpec(depth=int(qos.depth), deadline_s=_seconds(qos.deadline),
                   lifespan_s=_seconds(qos.lifespan),
                   liveliness_lease_duration_s=_seconds(qos.liveliness_lease_duration),
                   avoid_ros_namespace_conventions=bool(qos.avoid_ros_namespace_conventions),
                   **names)


def offered_qos(record_dir: str | Path) -> dict[str, tuple[QosSpec, ...]]:
    """Topic -> the QoS profiles a record's metadata says were offered on it (those that
    are fully known); a topic without any is left out (replay it with its default)."""
    from rosbags.rosbag2 import Reader
    out: dict[str, tuple[QosSpec, ...]] = {}
    with Reader(Path(record_dir)) as reader:
        for c in reader.connections:
            specs = tuple(s for s in map(from_rosbags,
                                         getattr(c.ext, "offered_qos_profiles", ()) or ())
                          if s is not None)
            if specs:
                out[c.topic] = specs
    return out
