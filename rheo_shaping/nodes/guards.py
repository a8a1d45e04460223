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
from ..safety.one_of_each import Announcement, settle_refusal, settle_time, twin_reason
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
    node of the same name is up (this one must then yield)."""

    def __init__(self, node: Node, on_twin: Callable[[str], None],
                 acting: Callable[[], bool] | None = None):
        """``acting``: whether the node has begun to act (default: once it has settled);
        from then on an announcement never makes it quit."""
        self._acting = acting or (lambda: self._settled)
        self.mine = Announcement(time.time_ns(), os.getpid(), socket.gethostname(),
                                 node.get_fully_qualified_name())
        self._node = node
        self._on_twin = on_twin
        self.twin = ""
        self._younger: set[Announcement] = set()   # same-name nodes that started after this
        self._settled: bool = False
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._t0 = self._start = self._steady.now().nanoseconds
        self._settle_s = settle_time(None)
        self._peer_s: float | None = None           # start -> the graph showed another node
        self._graph: frozenset[str] = frozenset()   # the graph's nodes, and when they changed
        self._graph_changed = self._start
        self._peer_timer = node.create_timer(0.05, self._look_for_peers, clock=self._steady)
        self._pub = node.create_publisher(T.PRESENCE.type, T.PRESENCE.name, T.PRESENCE.qos)
        node.create_subscription(T.PRESENCE.type, T.PRESENCE.name, self._on, T.PRESENCE.qos)
        self._pub.publish(String(data=self.mine.message()))

    def discovered(self) -> None:
        """Discovery has just reached the rest of the cell (its first latched message came):
        the settle time (:func:`~rheo_shaping.safety.one_of_each.settle_time`: at least as
        long as discovery took to show this node any other node) counts from now, so a
        twin's announcement that discovery brings with the same wave arrives before this
        node acts."""
        if not self._settled:
            self._look_for_peers()
            self._settle_s = settle_time(self._peer_s)
            self._t0 = self._steady.now().nanoseconds

    def _look_for_peers(self) -> None:
        """How long discovery took to show this node another node of the graph (the measure
        of discovery on this machine now, not of the other node's own start-up), and when
        the graph's set of nodes last changed (until this node has settled)."""
        if self._settled:
            self._node.destroy_timer(self._peer_timer)
            return
        now = self._steady.now().nanoseconds
        names = frozenset(f"{s.rstrip('/')}/{n}"
                          for n, s in self._node.get_node_names_and_namespaces())
        if names != self._graph:
            self._graph, self._graph_changed = names, now
        if self._peer_s is None and names - {self.mine.node}:
            self._peer_s = (now - self._start) / NS

    @property
    def settled(self) -> bool:
        """Whether this node knows it is the only (or the oldest) node of its name: at least
        the settle time after its start, and every other node of its name in the graph
        has announced itself as younger.  Latches once true."""
        if self._settled:
            return True
        if self.twin or (self._steady.now().nanoseconds - self._t0) / NS < self._settle_s:
            return False
        ns, _, name = self.mine.node.rpartition("/")

        def is_mine(n: str, s: str) -> bool:
            return n == name and (s.rstrip("/") or "") == ns
        writers = self._node.get_publishers_info_by_topic(self._pub.topic_name)
        why = settle_refusal(
            same_nodes=sum(is_mine(n, s) for n, s in self._node.get_node_names_and_namespaces()),
            same_writers=sum(is_mine(w.node_name, w.node_namespace) for w in writers),
            unnamed_writers=sum(w.node_name == UNNAMED for w in writers),
            younger=len(self._younger),
            past_settle_s=(self._steady.now().nanoseconds - self._t0) / NS - self._settle_s,
            graph_still_s=(self._steady.now().nanoseconds - self._graph_changed) / NS,
            settle_s=self._settle_s)
        self._settled = not why
        if why:
            self._node.get_logger().info(f"waiting: {why}", throttle_duration_sec=5.0)
        return self._settled

    def _on(self, msg: String) -> None:
        other = Announcement.parse(msg.data)
        if other is None:
            self._node.get_logger().warning(f"ignored a malformed {T.PRESENCE.contract}: "
                                            f"{msg.data[:80]!r}", throttle_duration_sec=5.0)
            return
        if other.node == self.mine.node and self.mine < other:
            self._younger.add(other)
        why = twin_reason(self.mine, other)
        if why and self._acting():
            # a running node never quits on an announcement: an older twin is found before
            # a node acts (the settle time), so an "older" one now is a forgery or a clock
            self._node.get_logger().error(f"ignored: {why} (announced after this node "
                                          f"started to act: it runs on)",
                                          throttle_duration_sec=5.0)
            return
        if why and not self.twin:
            self.twin = why
            self._on_twin(why)
