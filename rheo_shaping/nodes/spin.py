"""Running one node as a process: ``main()`` of simulator, planner and monitor.

In the style of ros2/demos: ``rclpy.init``, spin until SIGINT or an external
shutdown, destroy the node, exit 0.  An invalid parameter at start is logged
with the schema's message and exits with code 2.
"""
from __future__ import annotations

from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from ..schema import ParameterError


def run_node(factory: Callable[[], Node], name: str, args=None) -> int:
    rclpy.init(args=args)
    try:
        node = factory()
    except ParameterError as exc:
        rclpy.logging.get_logger(name).fatal(str(exc))
        rclpy.try_shutdown()
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        # Ctrl-C while the node is still being built (it is in the graph from its first
        # line on; the simulator then settles the sheet): a clean stop too.
        rclpy.logging.get_logger(name).info("interrupted while starting")
        rclpy.try_shutdown()
        return 0
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # rclpy's SIGINT handler shuts the context down asynchronously; when that lands
        # while the executor builds its wait set, rcl reports an invalid context
        # (ros2/rclpy#398, ros2/ros2cli#854).  That is the shutdown we asked for.
        if rclpy.ok():
            raise
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
