"""Running one node as a process: ``main()`` of simulator, planner and monitor.

In the style of ros2/demos: ``rclpy.init``, spin until SIGINT or an external
shutdown, destroy the node, exit 0.  An invalid parameter at start is logged
with the schema's message and exits with code 2; so is a params file that the
core refuses (:func:`rheo_shaping.params.config.check_params_file`, checked before
``rclpy.init``: the same rule and message as ``rheo-shaping simulate``) or that
rcl refuses: no traceback for a user's file.
"""
from __future__ import annotations

import signal
import sys
import sysconfig
from pathlib import Path
from typing import Callable, Iterable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from ..params.config import ConfigError, check_params_file
from ..params.schema import ParameterError
from .ros_params import set_command_line


def params_files(argv: Iterable[str]) -> list[str]:
    """The ``--params-file FILE`` of the ``--ros-args`` blocks, in order."""
    args, out, in_ros = list(argv), [], False
    for i, a in enumerate(args):
        if a == "--ros-args":
            in_ros = True
        elif a == "--":
            in_ros = False
        elif in_ros and a == "--params-file" and i + 1 < len(args):
            out.append(args[i + 1])
    return out


class _StopSignal:
    """SIGINT and SIGTERM as KeyboardInterrupt, remembering that one arrived.

    rclpy's C handler (installed by ``rclpy.init``) chains to this one, which Python runs
    at the next bytecode of the main thread.  When that bytecode belongs to Python code
    called from inside rclpy's C++ (a message's constructor while ``take_message`` builds
    it), pybind11 turns the KeyboardInterrupt into a ``RuntimeError`` ("Unable to convert
    call argument '0' to Python object"), possibly before rclpy's own thread has shut the
    context down (seen in CI: the simulator ended with exit 1 on the test's SIGINT).
    ``received`` tells :func:`run_node` that such an error is the stop that was asked for.

    Once ``rclpy.init`` has returned (``rclpy_stops``), a signal that lands in rclpy's own
    Python code raises nothing: rclpy's handler, which ran first, shuts the context down and
    that ends the spin (or the next rcl call of a node being built).  A KeyboardInterrupt
    raised there cut an executor's ``Task`` short in its constructor, and the half-built
    object's ``__del__`` printed a traceback at exit ("'Task' object has no attribute
    '_exception'"; seen in CI, the gap watch stopped on a busy machine).
    """

    def __init__(self) -> None:
        self.received: int | None = None
        self.rclpy_stops = False

    def __call__(self, signum, frame) -> None:
        first = self.received is None
        self.received = signum
        # a second signal finds the stop under way: the node is tearing down and must not
        # be cut short there
        if first and not (self.rclpy_stops and in_rclpy(frame)):
            raise KeyboardInterrupt

    def install(self) -> None:
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self)


#: rclpy's package directory: a frame whose code lies there is rclpy's own (:func:`in_rclpy`).
RCLPY_DIR = str(Path(rclpy.__file__).resolve().parent)


#: The standard library's directory: its frames are stepped past (:func:`in_rclpy`).
STDLIB_DIR = str(Path(sysconfig.get_paths()["stdlib"]).resolve())


def _stdlib(path: str) -> bool:
    """Whether source file ``path`` (resolved) is the standard library's (frozen modules
    included; installed packages, which may lie beneath it, not)."""
    return path.startswith("<frozen ") or (
        path.startswith(STDLIB_DIR + "/")
        and not {"site-packages", "dist-packages"} & set(Path(path).parts))


def in_rclpy(frame) -> bool:
    """Whether ``frame`` (where a signal handler interrupted the main thread) runs rclpy's
    own Python code, or the standard library's called from it (``inspect`` or ``enum`` in a
    ``Task``'s constructor): the first frame out from ``frame`` that is not the standard
    library's is rclpy's."""
    while frame is not None:
        name = frame.f_code.co_filename
        path = name if name.startswith("<") else str(Path(name).resolve())
        if path.startswith(RCLPY_DIR + "/"):
            return True
        if not _stdlib(path):
            return False
        frame = frame.f_back
    return False


class Yielded(Exception):
    """Raised in a node's callback when an older node of its name runs: the process ends
    with the reason (exit code 2), the older node runs on (docs/safety.md, "One of each")."""


def build_or_destroy(node: Node, build: Callable[..., None], *args) -> None:
    """Run ``build(*args)``, the rest of a node's construction; a node refused there (a
    parameter error) is destroyed at once, so it does not linger in the graph, where a new
    node of its name would wait for it (nodes.guards.Presence)."""
    try:
        build(*args)
    except BaseException:
        node.destroy_node()
        raise


def _fatal(name: str, message: str) -> int:
    print(f"[FATAL] [{name}]: {message}", file=sys.stderr, flush=True)
    return 2


def run_node(factory: Callable[[], Node], name: str, args=None, warm: bool = True) -> int:
    """Run one node executable to its end; its exit code.  ``warm``: load the compiled
    sheet step first (:func:`warm_up`), for a node that steps or plans the sheet."""
    argv = sys.argv if args is None else args
    user = list(argv[1:])
    if "--ros-args" in user:
        user = user[:user.index("--ros-args")]
    if "--version" in user:
        from .. import __version__
        print(f"{name} (rheo_shaping) {__version__}")
        return 0
    if "-h" in user or "--help" in user:
        print(f"usage: {name} [--version] [--ros-args --params-file FILE -p NAME:=VALUE "
              f"-r __ns:=/NS ...]\n\nThe rheo_shaping {name} node (docs/ros.md: topics, "
              f"parameters, QoS).")
        return 0
    for path in params_files(argv):
        try:
            check_params_file(path)
        except ConfigError as exc:
            return _fatal(name, str(exc))
    set_command_line(args)            # -p NAME:=VALUE beats the params file (ros_params)
    # the compiled sheet step, loaded (or compiled on a user's first run) while a signal
    # still ends the process at once (nodes/entry.py): nothing of ROS exists yet
    if warm:
        warm_up()
    stop = _StopSignal()
    try:
        # from here on rclpy's handlers (installed by init, chaining to these) stop the node
        stop.install()
        rclpy.init(args=args)
        stop.rclpy_stops = True
    except KeyboardInterrupt:
        return 0
    except Exception as exc:          # noqa: BLE001  rcl refuses the arguments (RCLError)
        return _fatal(name, f"ROS refused the command line: {str(exc).strip()}")
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
    except Exception:                 # noqa: BLE001
        # rclpy's handler shut the context down while the node was being built: rcl then
        # refuses the next timer or publisher ("the given context is not valid")
        if rclpy.ok() and stop.received is None:
            raise
        rclpy.logging.get_logger(name).info("interrupted while starting")
        return 0
    code = 0
    try:
        code = _spin(node, name, stop)
    except KeyboardInterrupt:
        # rclpy's C handler shut the context down and spin returned before Python ran our
        # handler, which then raised in the except clauses above: the stop we asked for
        pass
    finally:
        _teardown(node)
    return code


def _spin(node: Node, name: str, stop: "_StopSignal") -> int:
    """Spin ``node`` until it is stopped; its exit code (2: it yielded to an older node)."""
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Yielded as exc:
        rclpy.logging.get_logger(name).fatal(f"yields: {exc}")
        return 2
    except Exception:                 # noqa: BLE001
        # rclpy's SIGINT handler shuts the context down asynchronously; when that lands
        # while the executor builds its wait set, rcl reports an invalid context
        # (ros2/rclpy#398, ros2/ros2cli#854), and a KeyboardInterrupt raised inside
        # rclpy's C++ comes out as a RuntimeError (_StopSignal).  After a stop signal,
        # either is the shutdown we asked for; without one, it is a real failure.
        if rclpy.ok() and stop.received is None:
            raise
    return 0


def _teardown(node: Node) -> None:
    """Destroy ``node`` and shut rclpy down; once more if the stop signal's handler, run
    late (it raises once, on the first signal), cut the first pass short: the node leaves
    the graph cleanly instead of lingering there until its DDS lease runs out."""
    for _ in range(2):
        try:
            node.destroy_node()
            rclpy.try_shutdown()
            return
        except KeyboardInterrupt:
            continue


def warm_up() -> float:
    """Load (or, on a user's first run, compile) every entry of the compiled step the nodes
    use, by running a short process of the default cell (cake, workplane and tool shapes,
    the settle, a scenario) once; returns the wall time it took [s].

    The node executables call it before ``rclpy.init``, so that loading the compiled code
    (numba calls back into Python through ctypes while it loads) and a long first compile
    happen while a signal can still end the process at once (:mod:`.entry`)."""
    import time
    from dataclasses import replace

    from ..params.cell import CellParams
    from ..planning.movement import run_movement
    t0 = time.perf_counter()
    cell = CellParams()
    run_movement(replace(cell, movement=replace(cell.movement, process_time=5.0)))
    return time.perf_counter() - t0
