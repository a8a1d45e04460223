"""Settings of the ``lifecycle_manager`` node (rheo_shaping.safety.lifecycle): which nodes
it manages, in what order, and its time limits.  One schema with the other nodes
(:mod:`rheo_shaping.params.node_params`, ``docs/ros.md``).  No ROS imports here.
"""
from __future__ import annotations

from dataclasses import dataclass

from .schema import param


#: The nodes a lifecycle manager can manage, in the order it configures and activates them
#: (the planner last: it moves the tool, behind the monitor's interlock).
MANAGEABLE: tuple[str, ...] = ("simulator", "monitor", "gap_watch", "planner")
#: The nodes every managed cell has (``node_names`` must name them).
CELL_NODES: tuple[str, ...] = ("simulator", "monitor", "planner")


@dataclass(frozen=True)
class LifecycleManagerParams:
    """The ``lifecycle_manager`` node: brings the managed cell up in order and down to a safe
    state on a failure (rheo_shaping.safety.lifecycle)."""

    node_names: tuple = param(
        CELL_NODES, "the managed nodes of the cell in this namespace (Nav2's node_names): "
        "simulator, monitor and planner, and gap_watch to manage a gap_watch_managed too; "
        "brought up in the order simulator, monitor, gap_watch, planner whatever the order "
        "given; a node named here that is lost fails the cell", choices=MANAGEABLE,
        min_length=3)
    autostart: bool = param(
        True, "bring the cell up at start (configure, then activate simulator, monitor and, "
        "once the monitor is ready, planner); else wait for ~/startup")
    heartbeat_timeout: float = param(
        2.0, "wall-clock silence of a managed node's ~/heartbeat (sent every 0.1 s) after "
        "which the node counts as lost: the tool holds, the planner deactivates", "s", 0.1, 60.0,
        lo_open=True)
    transition_timeout: float = param(
        120.0, "wall-clock time a transition (configure settles the sheet or plans) may take "
        "before it counts as failed", "s", 0.0, 3600.0, lo_open=True)
    period: float = param(0.05, "steady-clock period of the manager's checks", "s", 0.0, 1.0,
                          lo_open=True)

    def __post_init__(self) -> None:
        missing = [n for n in CELL_NODES if n not in self.node_names]
        if missing:
            raise ValueError(f"parameter 'node_names' = {list(self.node_names)!r} is invalid: "
                             f"expected every node of a cell ({', '.join(CELL_NODES)}); "
                             f"missing {', '.join(missing)}")

    @property
    def nodes(self) -> tuple[str, ...]:
        """:attr:`node_names` in the order they are brought up (:data:`MANAGEABLE`)."""
        return tuple(n for n in MANAGEABLE if n in self.node_names)
