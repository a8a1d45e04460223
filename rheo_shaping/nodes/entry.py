"""Entry points of the node executables (``simulator``, ``planner``, ``monitor``; their
managed variants ``simulator_managed``, ``planner_managed``, ``monitor_managed``,
``gap_watch_managed``; the
``lifecycle_manager``; ``gap_watch``).

A signal must end a node cleanly at any moment of its start-up, with exit code 0 and
no traceback.  Before ``rclpy.init`` nothing of ROS exists yet, so SIGINT and SIGTERM
end the process at once (:func:`_early_exit`); this covers the imports (numpy, scipy,
numba) and the loading or first compilation of the sheet kernel
(:func:`rheo_shaping.nodes.spin.warm_up`), which therefore happen here, before ROS.  From
``rclpy.init`` on, rclpy's own handler shuts the context down and
:func:`rheo_shaping.nodes.spin.run_node` ends the node cleanly; once it returns, the process
ends at once with its code (no interpreter finalisation, during which a signal would kill
it).  This module imports nothing heavy, so its handlers are in place within milliseconds
of the start.  Before that, the interpreter's own start-up: the executable (setup.py's
``LAUNCHER``) starts Python with SIGINT and SIGTERM blocked, and :func:`_run` unblocks them
once its handlers are in place, so a signal that came in between is handled then.
"""
from __future__ import annotations

import os
import signal
import sys


def _early_exit(signum, frame) -> None:  # noqa: ARG001 - a signal handler's signature
    os.write(2, b"interrupted while starting\n")
    os._exit(0)


def _run(module: str, function: str = "main") -> int:
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _early_exit)
    # the executable (setup.py's LAUNCHER) starts Python with both blocked: a signal that came
    # during the interpreter's own start-up is pending, and is delivered to the handler now
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    import importlib
    node = importlib.import_module(f"rheo_shaping.nodes.{module}")
    try:
        code = getattr(node, function)()
    except KeyboardInterrupt:
        # a stop signal whose Python handler ran after the node had already stopped: the
        # stop asked for, not a crash (uncaught it would end the process by the signal, -2)
        code = 0
    # The node is done (stopped, or it refused its parameters).  The interpreter's own
    # finalisation (numba, llvmlite, scipy) takes seconds on a busy machine and restores the
    # default signal handlers first, so a Ctrl-C then would end the process by the signal
    # (exit -2): end here, with the node's own exit code.
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code if isinstance(code, int) else 0)


def simulator() -> int:
    return _run("simulator")


def planner() -> int:
    return _run("planner")


def monitor() -> int:
    return _run("monitor")


def simulator_managed() -> int:
    return _run("managed", "simulator_main")


def planner_managed() -> int:
    return _run("managed", "planner_main")


def monitor_managed() -> int:
    return _run("managed", "monitor_main")


def gap_watch_managed() -> int:
    return _run("managed", "gap_watch_main")


def lifecycle_manager() -> int:
    return _run("lifecycle_manager")


def gap_watch() -> int:
    return _run("gap_watch")


if __name__ == "__main__":  # pragma: no cover - python -m rheo_shaping.nodes.entry NODE ...
    name = sys.argv.pop(1) if len(sys.argv) > 1 else ""
    if name not in ("simulator", "planner", "monitor", "gap_watch"):
        sys.exit("usage: python -m rheo_shaping.nodes.entry simulator|planner|monitor|gap_watch "
                 "[--ros-args ...]")
    sys.exit(_run(name))
