"""Every stream a decision rests on is bound to the node that owns it (docs/ros.md, "Who may
write what").

The cell's nodes have fixed names in their namespace (``simulator``, ``monitor``,
``planner``): the monitor takes ``/sheet/tensions`` only from its simulator, the simulator
takes ``/shaping/checked`` only from its monitor, the planner and the lifecycle manager
take ``/shaping/ready`` only from the monitor, the manager takes each ``~/heartbeat`` only
from its node.  :class:`StreamOwner` is that rule for one stream, without ROS: it binds to
the one writer (its GID, from the graph) of the owner's name, and any other writer of the
stream makes the stream untrusted while the graph shows it, named once it has a name.
rclpy hands no writer GID to a callback, so the node asks the graph at every sample, and
the publication sequence numbers of the bound writer must rise
(:meth:`StreamOwner.accept`): a sample that arrives before the graph shows its writer is
taken only if it continues the bound writer's count.  What a node does with an untrusted
stream is its own safe reaction: the monitor aborts, the simulator holds the tool, the
planner does not move, the manager counts the node lost.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from .command_gate import UNNAMED, Publisher


@dataclass(frozen=True)
class Trust:
    """What the graph says of one stream now."""

    trusted: bool                     # the bound owner is its only writer
    reason: str                       # why not ("" when trusted)
    foreign: tuple[Publisher, ...]    # named writers that are not the owner's bound one


def unnamed(p: Publisher) -> bool:
    """Whether the graph does not know the node of writer ``p`` yet (ROS 2 learns an
    endpoint from DDS before it learns its node's name)."""
    return p.node.rsplit("/", 1)[-1] == UNNAMED


def owner_name(namespace: str, node: str) -> str:
    """The fully qualified name of the cell's node ``node`` in ``namespace``
    (``/cell2``, ``monitor`` -> ``/cell2/monitor``; root: ``/monitor``)."""
    ns = namespace.rstrip("/")
    return f"{ns}/{node}"


class StreamOwner:
    """One stream (``topic``) bound to the writer of the node ``owner`` (fully qualified)."""

    def __init__(self, topic: str, owner: str, strict: bool = True):
        """``strict`` False: any writer of the owner's name is taken, none of another name
        (a restarted node's writer while the killed one's stays in the graph for its DDS
        lease, ~20 s; for a stream that only reports, such as a heartbeat)."""
        self.topic, self.owner, self.strict = topic, owner, strict
        self.bound: Publisher | None = None
        self._seq = 0
        self._reported: set[str] = set()

    def judge(self, writers: Sequence[Publisher]) -> Trust:
        """Whether samples of the stream may be taken, given its writers in the graph now.
        Binds to the owner's writer when it is the only writer of the owner's name; lets a
        bound writer go when the graph no longer shows it (the owner was restarted)."""
        writers = list(writers)
        if not self.strict:
            foreign = tuple(w for w in writers if not unnamed(w) and w.node != self.owner)
            if foreign:
                return Trust(False, self.describe(foreign), foreign)
            if not any(w.node == self.owner for w in writers):
                return Trust(False, f"no writer of {self.topic} named {self.owner} in the "
                             f"graph", ())
            return Trust(True, "", ())
        if self.bound is not None and all(w.gid != self.bound.gid for w in writers):
            self.bound, self._seq = None, 0
        if self.bound is None:
            mine = [w for w in writers if w.node == self.owner]
            if len(mine) == 1:
                self.bound = mine[0]
        others = tuple(w for w in writers if self.bound is None or w.gid != self.bound.gid)
        foreign = tuple(w for w in others if not unnamed(w)
                        and not (self.bound is None and w.node == self.owner))
        if self.bound is None:
            n_mine = sum(w.node == self.owner for w in writers)
            why = (f"{n_mine} writers of {self.topic} named {self.owner}" if n_mine > 1
                   else f"no writer of {self.topic} named {self.owner} in the graph")
            if foreign:
                why += "; " + self.describe(foreign)
            return Trust(False, why, foreign)
        if others:
            why = (self.describe(foreign) if foreign else
                   f"{len(others)} writers of {self.topic} whose node the graph does not name "
                   f"yet, besides {self.owner}")
            return Trust(False, why, foreign)
        return Trust(True, "", ())

    def describe(self, foreign: Sequence[Publisher]) -> str:
        """The reason that names each foreign writer."""
        names = ", ".join(f"{p.node} ({p.gid[:12]})" for p in foreign)
        return (f"a second writer of {self.topic}: {names}; {self.topic} is taken only from "
                f"{self.owner}")

    def accept(self, seq: int) -> bool:
        """Whether a sample with publication sequence number ``seq`` continues the bound
        writer's count (0: no number known, e.g. an executor without message info)."""
        if not seq:
            return True
        if seq <= self._seq:
            return False
        self._seq = int(seq)
        return True

    def report_once(self, trust: Trust) -> bool:
        """True the first time these foreign writers are seen (report them then)."""
        key = ",".join(sorted(p.gid for p in trust.foreign))
        if not key or key in self._reported:
            return False
        self._reported.add(key)
        return True
