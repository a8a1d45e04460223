"""Every use of rclpy's private attributes, in one place (rclpy of ROS 2 Jazzy).

rclpy offers no public API for three things this package needs: the node's time source
(its ``/clock`` subscription, which the clock guard puts itself in front of), the
parameter overrides a node was started with (the schema checks them before declaring), and
a lifecycle node's state machine (its state's label, its handle on destruction).  Each is
one function here; nothing else in the package touches a private attribute of rclpy
(test/architecture/test_rclpy_private.py holds that).
"""
from __future__ import annotations

from typing import Any, Callable

from rclpy.lifecycle import LifecycleNodeMixin
from rclpy.node import Node
from rclpy.subscription import Subscription
from rclpy.time_source import TimeSource


def clock_subscription(node: Node) -> Subscription | None:
    """The node's time source's ``/clock`` subscription (None on wall time)."""
    return node._time_source._clock_sub


ClockCallback = Callable[[Any], None]


def wrap_clock_callback(node: Node, wrap: Callable[[ClockCallback], ClockCallback]) -> None:
    """Replace the time source's ``/clock`` callback by ``wrap(original)`` and subscribe
    again with it (same topic, so remaps such as ``/clock:=clock`` hold)."""
    ts = node._time_source
    # the instance's callback replaces the class's method (setattr: mypy refuses assigning
    # to a method, which is what this does on purpose)
    setattr(ts, "clock_callback", wrap(lambda msg: TimeSource.clock_callback(ts, msg)))
    if ts._clock_sub is not None:
        node.destroy_subscription(ts._clock_sub)
        ts._clock_sub = None
        ts._subscribe_to_clock_topic()


def parameter_overrides(node: Node) -> dict:
    """The parameter overrides the node was made with (params file, ``-p``), by name; the
    dict itself: an entry set here is applied when the parameter is declared."""
    overrides = getattr(node, "_parameter_overrides", None)
    if overrides is None:
        overrides = node._parameter_overrides = {}
    return overrides


def lifecycle_label(node: LifecycleNodeMixin) -> str:
    """A lifecycle node's primary state's label (unconfigured, inactive, active, ...)."""
    return node._state_machine.current_state[1]


def release_state_machine(node: LifecycleNodeMixin) -> None:
    """Let a lifecycle node's state machine go with the node (rclpy keeps its handle)."""
    node._state_machine.destroy_when_not_in_use()
