"""One ROS session of a command that is not a node executable (``rheo-shaping cell``,
``record-cell``, ``replay``): a context of its own, ``rclpy.init`` on it, an executor, and
on the way out (also on an exception) the executor shut down, every node destroyed, the
context shut down.  Node executables use :func:`.spin.run_node` (signals, exit codes)."""
from __future__ import annotations

from contextlib import contextmanager
from typing import Callable, Iterator

import rclpy
from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node


@contextmanager
def ros_session(args: list[str], executor_type: Callable[..., Executor] = SingleThreadedExecutor
                ) -> Iterator[tuple[Context, Executor, list[Node]]]:
    """``with ros_session(args) as (context, executor, nodes):`` make nodes on ``context``,
    append them to ``nodes`` and add them to ``executor``; all are torn down on exit."""
    context = Context()
    rclpy.init(args=args, context=context)
    nodes: list[Node] = []
    executor = None
    try:
        executor = executor_type(context=context)
        yield context, executor, nodes
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        for node in reversed(nodes):
            node.destroy_node()
        rclpy.try_shutdown(context=context)


def eta(elapsed_s: float, done: float, total: float) -> str:
    """", ETA N s" for a command's progress line: the time [s] left at the pace so far
    (``done`` of ``total``, in any one unit, ``elapsed_s`` [s] for it); "" before the
    first part or after the end."""
    if not 0 < done < total:
        return ""
    return f", ETA {elapsed_s * (total - done) / done:4.0f} s"
