"""One of each: a second simulator, planner or monitor of a name yields (docs/safety.md).

Every node announces itself once on ``/shaping/presence`` (latched): its fully qualified
name, its start time and its process.  A node that reads the announcement of another node
of its own name that started earlier yields to it (it stops with the reason); the older
one runs on.  A node acts (starts a plan, reports ready, steps the sheet) only
:func:`settle_time` after its own start, so that an older twin's announcement has arrived
by then.  Ties of start time go to the smaller process id, then host name.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from typing import Callable

from ..params.wire import Field, WireError, read_fields

#: Wall-clock time [s] a node waits after its start (the planner: after the simulator's
#: first latched message, i.e. once discovery reached the cell) before it acts: an older
#: twin's latched announcement arrives within DDS discovery, under a second on one idle host.
SETTLE_TIME = 1.0


def settle_time(discovery_s: float | None) -> float:
    """How long [s] a node waits, from the moment discovery reached the rest of the cell,
    before it acts: :data:`SETTLE_TIME`, or as long as discovery took to show it another node
    of the graph (``discovery_s`` [s] from the node's start; None if unknown) when that was
    longer.  An older twin is found by the same discovery as the rest of the cell, so on a
    busy machine, where discovery is slow, the wait grows with it (seen: a newcomer planner
    that settled after 1 s at a load average of 20 had not yet seen the older planner and
    took a start)."""
    if discovery_s is None or not discovery_s > SETTLE_TIME:
        return SETTLE_TIME
    return float(discovery_s)


@dataclass(frozen=True, order=True)
class Announcement:
    """Who a node is: ordered by start time [ns since the epoch], then pid and host."""

    start_ns: int
    pid: int
    host: str
    node: str                 # fully qualified node name (/cell2/planner)

    def message(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)

    @classmethod
    def parse(cls, text: str) -> "Announcement | None":
        """The announcement in ``text`` (:func:`~rheo_shaping.params.wire.read_fields`:
        exactly its four keys, finite integers); None for anything else (ignored)."""
        try:
            d = read_fields(text, ANNOUNCEMENT_FIELDS, max_chars=4096, max_depth=1)
        except WireError:
            return None
        return cls(d["start_ns"], d["pid"], d["host"], d["node"])


#: The keys of an announcement and what each may hold.
ANNOUNCEMENT_FIELDS = {"start_ns": Field(int, 0, 2**63 - 1), "pid": Field(int, 0, 2**31),
                       "host": Field(str, max_len=255), "node": Field(str, max_len=1024)}


def twin_reason(mine: Announcement, other: Announcement) -> str:
    """Why ``mine`` must yield to ``other``: "" unless ``other`` is another node of the same
    name that started first."""
    if other.node != mine.node or other == mine or not other < mine:
        return ""
    return (f"a second {mine.node} in this namespace: the one of pid {other.pid} on "
            f"{other.host} started first and runs; this one (pid {mine.pid}) yields")


#: How long [s] past its settle time a node waits for the names of endpoints on
#: ``/shaping/presence`` that the graph shows without a node name yet (ROS 2 learns an
#: endpoint from DDS before it learns its node's name); a writer whose name never comes
#: (not a ROS node) is then disregarded.
UNNAMED_WAIT = 10.0


def settle_refusal(same_nodes: int, same_writers: int, unnamed_writers: int, younger: int,
                   past_settle_s: float, graph_still_s: float = math.inf,
                   settle_s: float = SETTLE_TIME) -> str:
    """Why a node may not act yet ("" if it may), past its settle time: ``same_nodes``
    nodes of its name in the graph and ``same_writers`` writers on ``/shaping/presence``
    of a node of its name (itself included in both), ``unnamed_writers`` writers there whose
    node name the graph does not know yet, ``younger`` same-named nodes that announced
    themselves as younger, ``past_settle_s`` [s] since the settle time ran out.  The
    writers are known before the node names (seen: a twin planner's command writer in the
    simulator's graph as ``_NODE_NAME_UNKNOWN_`` while the twin had not yet seen the older
    planner's name), so both counts are asked.  ``graph_still_s`` [s]: how long the graph's
    set of nodes has not changed; a node acts only once it held still for ``settle_s``
    (discovery brings the nodes one participant at a time, and on a busy machine an older
    twin can come seconds after the rest of the cell: seen at a load average of 10, a
    newcomer planner that had seen the simulator and the monitor but not yet the older
    planner); for at most ``UNNAMED_WAIT`` past the settle time (a large system whose nodes
    come and go never holds still).  A twin already in the graph is named first."""
    same = max(same_nodes, same_writers)
    if same - 1 > younger:
        return (f"{same} nodes of this name in the graph and {younger} announced as younger; "
                f"one that was killed stays in the graph for up to ~20 s (its DDS lease)")
    if unnamed_writers and past_settle_s < UNNAMED_WAIT:
        return (f"{unnamed_writers} writers on /shaping/presence whose node name the graph "
                f"does not show yet (a twin may be among them)")
    if graph_still_s < settle_s and past_settle_s < UNNAMED_WAIT:
        return (f"the graph's nodes changed {graph_still_s:.1f} s ago: waiting until they hold "
                f"still for {settle_s:.1f} s (discovery may still bring a twin)")
    return ""


def commander_refusal(bound: str | None, expected: bool = True) -> str:
    """Why a planner may not make its ``/tool/command`` writer yet ("" if it may): the
    simulator's latched ``/shaping/commander`` (``bound``: the node name of the planner it
    follows, "" for none, None before the message came) names another planner: an older one
    that runs (this one's twin, whose announcement may come later than the simulator's on a
    busy machine), or one that was killed and whose writer the graph still shows.  A writer
    made then would be a second commander, and the simulator would hold the tool.
    ``expected``: the cell's simulator says it (``check_cell``: a simulator or robot
    adapter that publishes its cell publishes its commander): wait for the message, which
    may come after the cell's on a busy machine."""
    if bound is None:
        return ("waiting for the simulator's commander on /shaping/commander" if expected
                else "")
    if bound:
        return (f"the simulator follows {bound}: a planner makes its /tool/command writer only "
                f"once the simulator follows none (that one ends, its DDS lease runs out after "
                f"a kill, or the simulator's ~/reset)")
    return ""


def cell_refusal(who: str, settled: bool, check_cell: bool,
                 mismatch: Callable[[], str | None], clocks: Callable[[], str],
                 cell_topic: str) -> tuple[str, bool]:
    """(why ``who`` may not act yet, whether that is a fault to stop on): still checking for
    a twin of its name; with ``check_cell``, no cell fingerprint from the simulator on
    ``cell_topic`` yet (``mismatch()`` None: wait) or another cell (``mismatch()``: the
    differing parameters, a fault); a second clock (``clocks()``: a fault).  Each question
    (a graph query of the node) is asked only when the ones before it passed."""
    if not settled:
        return f"starting up: checking that no other {who} of this name runs", False
    if check_cell:
        why = mismatch()
        if why is None:
            return (f"waiting for the simulator's cell on {cell_topic} (the fingerprint of "
                    f"every cell parameter; check_cell false for a cell without one)"), False
        if why:
            return why, True
    second = clocks()
    return second, bool(second)


class PresenceWatch:
    """A node's side of "one of each" without ROS: its announcement, the twins and younger
    nodes of its name it has heard of, how long discovery took, when the graph last
    changed, and whether it has settled (latched).  Times are steady-clock nanoseconds;
    the node asks the graph and forwards what it reads."""

    def __init__(self, mine: Announcement, now_ns: int):
        self.mine = mine
        self.twin = ""                              # why this node must yield ("" none)
        self.younger: set[Announcement] = set()     # same-name nodes announced as younger
        self.settled = False
        self.start_ns = self.t0_ns = now_ns         # its start; the settle time counts from t0
        self.settle_s = settle_time(None)
        self.peer_s: float | None = None            # start -> the graph showed another node
        self.graph: frozenset[str] = frozenset()    # the graph's nodes, and when they changed
        self.graph_changed_ns = now_ns

    def seen(self, names: frozenset[str], now_ns: int) -> None:
        """The graph's nodes now (fully qualified names): when they last changed, and how
        long discovery took to show this node another one."""
        if names != self.graph:
            self.graph, self.graph_changed_ns = names, now_ns
        if self.peer_s is None and names - {self.mine.node}:
            self.peer_s = (now_ns - self.start_ns) / 1e9

    def discovered(self, now_ns: int) -> None:
        """Discovery has reached the rest of the cell: the settle time (at least as long as
        discovery took to show this node another one) counts from now."""
        if not self.settled:
            self.settle_s = settle_time(self.peer_s)
            self.t0_ns = now_ns

    def due(self, now_ns: int) -> bool:
        """Whether the graph is to be asked if this node may settle: not settled, no twin,
        its settle time over."""
        return (not self.settled and not self.twin
                and (now_ns - self.t0_ns) / 1e9 >= self.settle_s)

    def settle(self, now_ns: int, same_nodes: int, same_writers: int,
               unnamed_writers: int) -> str:
        """Why it may not act yet (:func:`settle_refusal` on the graph's counts); settles
        (latched) when ""."""
        why = settle_refusal(
            same_nodes=same_nodes, same_writers=same_writers, unnamed_writers=unnamed_writers,
            younger=len(self.younger),
            past_settle_s=(now_ns - self.t0_ns) / 1e9 - self.settle_s,
            graph_still_s=(now_ns - self.graph_changed_ns) / 1e9, settle_s=self.settle_s)
        self.settled = not why
        return why

    def heard(self, other: Announcement, acting: bool) -> tuple[str, bool]:
        """An announcement: (why this node would yield, whether it yields now).  A node that
        already acts never quits on one (an older twin is found before a node acts, so an
        "older" one now is a forgery or a clock); a twin found before is not named twice."""
        if other.node == self.mine.node and self.mine < other:
            self.younger.add(other)
        why = twin_reason(self.mine, other)
        if not why or acting or self.twin:
            return why, False
        self.twin = why
        return why, True
