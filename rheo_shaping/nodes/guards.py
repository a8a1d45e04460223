"""What a node takes from others only after checks of its own (docs/safety.md): the clock,
the cell, its twins.  Thin ROS glue around the core's rules
(:class:`~rheo_shaping.safety.clock_guard.ClockGuard`,
:func:`~rheo_shaping.params.fingerprint.cell_mismatch`,
:mod:`~rheo_shaping.safety.one_of_each`).
"""
from __future__ import annotations

import os
import socket
import time
from typing import Any, Callable, cast

from rclpy.clock import Clock, ClockType, ROSClock
from rclpy.node import Node
from std_msgs.msg import String

from ..params.fingerprint import cell_mismatch
from ..params.cell import CellParams
from ..safety.clock_guard import ClockGuard
from ..safety.command_gate import UNNAMED, Publisher
from ..safety.one_of_each import Announcement, PresenceWatch
from ..safety.owners import StreamOwner, Trust, owner_name
from ..units import NS
from . import topics as T
from .rclpy_private import clock_subscription, wrap_clock_callback


def guard_clock(node: Node, guard: ClockGuard, on_fault: Callable[[str], None]) -> None:
    """Put ``guard`` in front of the node's time source: a refused ``/clock`` value is not
    applied (the node's clock keeps the last accepted one) and ``on_fault(reason)`` is called.

    rclpy's TimeSource subscribes its bound ``clock_callback``; the subscription is made
    again with the guarded one (same topic, so remaps such as ``/clock:=clock`` hold).  A
    negative time never reaches rclpy (whose ``Time`` would raise in the executor)."""
    def wrap(apply: Callable) -> Callable:
        def callback(msg) -> None:
            t_ns = int(msg.clock.sec) * NS + int(msg.clock.nanosec)
            why = guard.check(t_ns)
            if why:
                on_fault(why)
                return
            apply(msg)
        return callback

    wrap_clock_callback(node, wrap)


def sim_time_active(node: Node) -> bool:
    """Whether the node's clock follows /clock (``use_sim_time`` and a /clock heard).  A
    node's clock is a ``ROSClock``; rclpy annotates ``get_clock()`` as its base ``Clock``."""
    clock = node.get_clock()
    assert isinstance(clock, ROSClock)
    return clock.ros_time_is_active


def with_message_info(callback: Callable[[Any, Any], None]) -> Callable[[Any], None]:
    """``callback(msg, info)`` as ``create_subscription`` takes it: rclpy passes the message
    info to a callback of two parameters, but annotates only the one-parameter form."""
    return cast(Callable[[Any], None], callback)


def publishers_of(node: Node, topic: str) -> list[Publisher]:
    """The writers of ``topic`` (a resolved name) as the graph shows them now."""
    return [Publisher(f"{i.node_namespace.rstrip('/')}/{i.node_name}",
                      ".".join(f"{b:02x}" for b in i.endpoint_gid))
            for i in node.get_publishers_info_by_topic(topic)]


#: Longest time [s] an owned stream is taken on the graph's writer count alone (one writer,
#: the owner's at the last full check) before its writers' GIDs are asked again.
FULL_CHECK_S = 0.2
TRUSTED = Trust(True, "", ())


class OwnedStream:
    """A stream of ``node`` taken only from the cell's node ``owner`` of its namespace (the
    core's :class:`~rheo_shaping.safety.owners.StreamOwner`, asked of the graph at each
    sample).  A foreign writer is logged once with its node name."""

    def __init__(self, node: Node, topic: str, owner: str, strict: bool = True):
        self._node = node
        self.topic = node.resolve_topic_name(topic)
        self.core = StreamOwner(self.topic, owner_name(node.get_namespace(), owner), strict)
        self._trusted_at: float | None = None     # monotonic time of the last full judgement

    def trust(self) -> Trust:
        # the graph's writer count (10 us) at every sample; its writers with their GIDs
        # (90 us) when the count is not the one trusted writer, and every FULL_CHECK_S
        now = time.monotonic()
        if (self._trusted_at is not None and now - self._trusted_at < FULL_CHECK_S
                and self._node.count_publishers(self.topic) == 1):
            return TRUSTED
        trust = self.core.judge(publishers_of(self._node, self.topic))
        self._trusted_at = now if trust.trusted else None
        if trust.foreign and self.core.report_once(trust):
            self._node.get_logger().error(f"refused: {trust.reason}")
        return trust

    def take(self, info=None) -> Trust:
        """The trust of a sample just received (``info``: its rmw message info, when the
        executor passes it): untrusted also when its sequence number does not continue the
        bound writer's."""
        trust = self.trust()
        seq = int((info or {}).get("publication_sequence_number", 0))
        if trust.trusted and not self.core.accept(seq):
            return Trust(False, f"a sample of {self.topic} out of {self.core.owner}'s sequence "
                         f"(number {seq}): another writer", ())
        return trust


def second_clock(node: Node) -> str:
    """Why the clock the node's time source follows is not one simulator's: "" when its
    topic has at most one publisher (or the node is on wall time)."""
    sub = clock_subscription(node)
    if sub is None:
        return ""
    clocks = node.count_publishers(sub.topic_name)
    if clocks <= 1:
        return ""
    return (f"{clocks} publishers of {sub.topic_name}: one simulator is the cell's clock (for "
            f"several simulated cells on one domain, give every node of each cell "
            f"{' '.join(T.CLOCK_REMAP)})")


class CellCheck:
    """The simulator's cell (latched on ``/shaping/cell``) against this node's own."""

    def __init__(self, node: Node, own_name: str, cell: Callable[[], CellParams],
                 on_first: Callable[[], None] = lambda: None):
        self.own_name, self._cell, self._on_first = own_name, cell, on_first
        self.message: str | None = None     # the simulator's cell message, once received
        self._judged: tuple = (None, None, None)   # (message, cell, mismatch) last judged
        node.create_subscription(T.CELL.type, T.CELL.name, self._on, T.CELL.qos)

    def _on(self, msg: String) -> None:
        first = self.message is None
        self.message = msg.data
        if first:
            self._on_first()

    def mismatch(self) -> str | None:
        """None while no cell has arrived; "" when it is this node's; else the reason."""
        if self.message is None:
            return None
        cell = self._cell()
        message, judged, why = self._judged
        if message is not self.message or judged is not cell:    # asked at every tick
            why = cell_mismatch(cell, self.message, self.own_name, "the simulator")
            self._judged = (self.message, cell, why)
        return why


class Presence:
    """Announces the node on ``/shaping/presence``; calls ``on_twin(reason)`` when an older
    node of the same name is up (this one must then yield).  The decisions are the core's
    :class:`~rheo_shaping.safety.one_of_each.PresenceWatch`; this asks the graph."""

    def __init__(self, node: Node, on_twin: Callable[[str], None],
                 acting: Callable[[], bool] | None = None):
        """``acting``: whether the node has begun to act (default: once it has settled);
        from then on an announcement never makes it quit."""
        self._node = node
        self._on_twin = on_twin
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.core = PresenceWatch(Announcement(time.time_ns(), os.getpid(), socket.gethostname(),
                                               node.get_fully_qualified_name()),
                                  self._steady.now().nanoseconds)
        self._acting = acting or (lambda: self.core.settled)
        self.mine = self.core.mine
        self._peer_timer = node.create_timer(0.05, self._look_for_peers, clock=self._steady)
        self._pub = node.create_publisher(T.PRESENCE.type, T.PRESENCE.name, T.PRESENCE.qos)
        node.create_subscription(T.PRESENCE.type, T.PRESENCE.name, self._on, T.PRESENCE.qos)
        self._pub.publish(String(data=self.mine.message()))

    @property
    def twin(self) -> str:
        return self.core.twin

    def discovered(self) -> None:
        """Discovery has just reached the rest of the cell (its first latched message came):
        the settle time counts from now (core: PresenceWatch.discovered)."""
        if not self.core.settled:
            self._look_for_peers()
            self.core.discovered(self._steady.now().nanoseconds)

    def _look_for_peers(self) -> None:
        """The graph's nodes, until this node has settled."""
        if self.core.settled:
            self._node.destroy_timer(self._peer_timer)
            return
        self.core.seen(frozenset(f"{s.rstrip('/')}/{n}"
                                 for n, s in self._node.get_node_names_and_namespaces()),
                       self._steady.now().nanoseconds)

    @property
    def settled(self) -> bool:
        """Whether this node knows it is the only (or the oldest) node of its name (core:
        PresenceWatch.settle).  Latches once true."""
        now = self._steady.now().nanoseconds
        if not self.core.due(now):
            return self.core.settled
        ns, _, name = self.mine.node.rpartition("/")

        def is_mine(n: str, s: str) -> bool:
            return n == name and (s.rstrip("/") or "") == ns
        writers = self._node.get_publishers_info_by_topic(self._pub.topic_name)
        why = self.core.settle(
            now, sum(is_mine(n, s) for n, s in self._node.get_node_names_and_namespaces()),
            sum(is_mine(w.node_name, w.node_namespace) for w in writers),
            sum(w.node_name == UNNAMED for w in writers))
        if why:
            self._node.get_logger().info(f"waiting: {why}", throttle_duration_sec=5.0)
        return self.core.settled

    def _on(self, msg: String) -> None:
        other = Announcement.parse(msg.data)
        if other is None:
            self._node.get_logger().warning(f"ignored a malformed {T.PRESENCE.contract}: "
                                            f"{msg.data[:80]!r}", throttle_duration_sec=5.0)
            return
        acting = self._acting()
        why, yields = self.core.heard(other, acting)
        if why and acting:
            self._node.get_logger().error(f"ignored: {why} (announced after this node "
                                          f"started to act: it runs on)",
                                          throttle_duration_sec=5.0)
        if yields:
            self._on_twin(why)
