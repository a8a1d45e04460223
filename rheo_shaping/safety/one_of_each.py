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
