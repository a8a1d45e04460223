"""A client of a cell's ``lifecycle_manager``, in the manner of Nav2's
``nav2_lifecycle_manager.LifecycleManagerClient``: ``startup``, ``pause``, ``resume``,
``reset``, ``shutdown`` (the manager's ``~/manage_nodes``) and ``is_active``.

A command acts, so it is sent once: its reply can be lost to discovery on a busy machine
(:mod:`rheo_shaping.nodes.services`), then the answer is None and the manager's
``~/status`` says what happened.  ``is_active`` is a query, sent again while no reply came.

    node = rclpy.create_node("my_cell_tool")
    cell = LifecycleManagerClient(node, "/cellA")
    cell.pause()          # every node deactivated: the tool holds
    cell.resume()         # the latches cleared in order, the planner behind the interlock
"""
from __future__ import annotations

import time
from typing import Callable

import rclpy
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rclpy.node import Node
from std_srvs.srv import Trigger

from ..safety.lifecycle_terms import COMMANDS
from .services import query


class LifecycleManagerClient:
    """The lifecycle manager of the cell in ``namespace`` ("" the root), through ``node``.
    ``spin_once(seconds)`` spins the executor that holds ``node`` (default: rclpy.spin_once
    on ``node`` alone, for a node no executor spins)."""

    def __init__(self, node: Node, namespace: str = "",
                 spin_once: Callable[[float], None] | None = None):
        base = f"{namespace.rstrip('/')}/lifecycle_manager"
        self._manage = node.create_client(ChangeState, f"{base}/manage_nodes")
        self._is_active = node.create_client(Trigger, f"{base}/is_active")
        self._spin = spin_once or (lambda s: rclpy.spin_once(node, timeout_sec=s))

    def startup(self, timeout_s: float = 30.0) -> bool | None:
        """Configure and activate the cell (a recovery: the latches cleared in order)."""
        return self.command("startup", timeout_s)

    def pause(self, timeout_s: float = 30.0) -> bool | None:
        """Deactivate every node in reverse order: the planner stops, the tool holds."""
        return self.command("pause", timeout_s)

    def resume(self, timeout_s: float = 30.0) -> bool | None:
        """Activate the paused cell again, its latches cleared in order."""
        return self.command("resume", timeout_s)

    def reset(self, timeout_s: float = 30.0) -> bool | None:
        """Deactivate and clean up every node (``startup`` configures them again)."""
        return self.command("reset", timeout_s)

    def shutdown(self, timeout_s: float = 30.0) -> bool | None:
        """Reset, then shut every node down (finalized: start its process again)."""
        return self.command("shutdown", timeout_s)

    def command(self, name: str, timeout_s: float = 30.0) -> bool | None:
        """Send one of :data:`~rheo_shaping.safety.lifecycle.COMMANDS` once; whether the
        manager took it, None when no reply came within ``timeout_s`` [s]."""
        if name not in COMMANDS:
            raise ValueError(f"command {name!r}: expected one of {', '.join(COMMANDS)}")
        end = time.monotonic() + timeout_s
        while not self._manage.service_is_ready():
            if time.monotonic() > end:
                return None
            self._spin(0.05)
        future = self._manage.call_async(ChangeState.Request(
            transition=Transition(label=name)))
        while not future.done():
            if time.monotonic() > end:
                self._manage.remove_pending_request(future)
                return None
            self._spin(0.05)
        return bool(future.result().success)

    def is_active(self, timeout_s: float = 30.0) -> bool | None:
        """Whether the cell is active (the tool can move); None when no reply came."""
        end = time.monotonic() + timeout_s
        while not self._is_active.service_is_ready():
            if time.monotonic() > end:
                return None
            self._spin(0.05)
        answer = query(self._is_active, Trigger.Request(), self._spin,
                       max(end - time.monotonic(), 0.0))
        return None if answer is None else bool(answer.success)
