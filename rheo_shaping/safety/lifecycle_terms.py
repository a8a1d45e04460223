"""The managed cell's vocabulary (docs/ros.md, "Managed start-up").

The managed nodes (``simulator_managed``, ``monitor_managed``, ``planner_managed``,
``gap_watch_managed``) are ROS 2 lifecycle nodes: ``unconfigured`` -> configure ->
``inactive`` -> activate -> ``active``, and back by deactivate and cleanup; shutdown ends in
``finalized``.  The lifecycle manager drives them through their lifecycle services.  Here:
the primary states and transitions, the cell's bring-up, interlock and reset orders, Nav2's
commands, the manager's retry counts and times, one step the manager takes and what it knows
of a node; :class:`rheo_shaping.safety.lifecycle.CellLifecycle` decides with them.  No ROS.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..params.manager_params import CELL_NODES

#: The managed nodes of a cell, in the order they are configured and activated (the
#: lifecycle manager's default ``node_names``).
CELL_ORDER: tuple[str, ...] = CELL_NODES
#: The node whose readiness the interlocked node waits for, and that node.
INTERLOCK: tuple[str, str] = ("monitor", "planner")
#: The order in which a recovery clears the nodes' latches (their ``~/reset``): the monitor
#: first (the simulator refuses to release its hold while its monitor is lost), the planner
#: last (it runs again only behind a ready monitor and a tool that follows).
RESET_ORDER: tuple[str, ...] = ("monitor", "simulator", "planner")
#: Refused resets of a recovery tried again, one every :data:`RESET_RETRY_S`, before the cell
#: fails: a killed node's writers stay in the DDS graph for its lease (~20 s), and the
#: simulator refuses to release its hold while a second writer of its monitor's
#: acknowledgements is there.
RESET_RETRIES = 40
RESET_RETRY_S = 1.0
#: Nav2's lifecycle manager's commands (nav2_msgs/ManageLifecycleNodes: STARTUP 0, PAUSE 1,
#: RESUME 2, RESET 3, SHUTDOWN 4), by their number: startup configures and activates, pause
#: deactivates (the tool holds), resume activates again (clearing the latches), reset
#: deactivates and cleans up, shutdown also shuts every node down (finalized).
COMMANDS: tuple[str, ...] = ("startup", "pause", "resume", "reset", "shutdown")
#: A transition request that its node's heartbeats show no sign of for this long [s] (the
#: same process beating in the same state, no transition counted) did not arrive: a request
#: written before the restarted node's service had matched the manager's client is lost
#: (no durability for services); it is sent again.  A node in a transition beats no more
#: (the transition runs in its executor), and a request that arrived is served between two
#: beats: ten beats unchanged say it never came.
UNHEARD_S = 1.0
#: A managed node's heartbeat period [s] (steady clock).
HEARTBEAT_PERIOD = 0.1
#: Refused activations of the interlocked node tried again before the cell fails (its view of
#: the monitor's heartbeat may lag the manager's by a beat).
ACTIVATE_RETRIES = 3

UNCONFIGURED, INACTIVE, ACTIVE, FINALIZED = "unconfigured", "inactive", "active", "finalized"
#: The primary states of the ROS 2 node lifecycle (design.ros2.org, "Managed nodes").
PRIMARY_STATES = (UNCONFIGURED, INACTIVE, ACTIVE, FINALIZED)
#: Each transition the manager asks for and the primary state it ends in.
TRANSITIONS: dict[str, str] = {"configure": INACTIVE, "activate": ACTIVE,
                               "deactivate": INACTIVE, "cleanup": UNCONFIGURED,
                               "shutdown": FINALIZED}


def interlock_refusal(monitor_state: str, monitor_ready: bool) -> str:
    """Why the planner may not activate (or move) now; "" when it may: only while the monitor
    is ``active`` and reports ready (safety principle 6 as lifecycle states)."""
    if monitor_state != ACTIVE:
        return f"the monitor is {monitor_state or 'not seen yet'}, not active"
    if not monitor_ready:
        return "the monitor is active but not ready (no fresh, valid tension data yet)"
    return ""


@dataclass(frozen=True)
class Step:
    """One thing the manager does now: ``transition`` (a key of :data:`TRANSITIONS`) of
    ``node``, or ``hold`` (publish ``reason`` on /shaping/abort: the tool holds)."""

    action: str
    node: str = ""
    reason: str = ""


@dataclass
class NodeSeen:
    """What the manager knows of one managed node."""

    state: str = ""                   # the primary state of its newest heartbeat ("" none yet)
    beat_ns: int | None = None        # steady time of that heartbeat
    instance: str = ""                # which process sent it (a restarted node is another)
    transitions: int = 0              # transitions it had completed when it sent it
    pending: str = ""                 # a transition asked for, not answered yet
    asked_at: int = 0                 # its transition count when the pending one was asked
    refused: int = 0                  # refused activations in a row
    activated: bool = False           # activated by this bring-up (expected active since)
    latch: str = ""                   # its latched hold or abort ("" none), from its beat
    asked_ns: int = 0                 # steady time the pending transition was (re)sent
    resent: int = 0                   # times the pending transition was sent again
    heard: tuple[str, str, int] = ("", "", 0)   # the newest beat: (instance, state, count)
    refusal: tuple[str, int] | None = None      # a re-sent request's refusal, and when
