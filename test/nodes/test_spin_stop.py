"""run_node: an error that a stop signal caused is the requested shutdown (exit 0); the
same error without a signal is a failure that must surface.

rclpy's C++ turns a KeyboardInterrupt raised in Python code it calls (a message's
constructor inside ``take_message``) into ``RuntimeError("Unable to convert call argument
'0' to Python object")``, possibly before its own thread has shut the context down (seen
once in CI: the simulator exited 1 on a test's SIGINT).  The node below mimics that at
will: its timer sends itself SIGINT and turns the KeyboardInterrupt into that RuntimeError.
Each case runs in a process of its own (run_node installs signal handlers and inits rclpy).
"""
from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy")

NODE = textwrap.dedent("""
    import os, signal, sys
    from rclpy.node import Node
    from rheo_shaping.nodes.spin import run_node

    SIGNAL = sys.argv[1] == "signal"

    class Converts(Node):
        def __init__(self):
            super().__init__("converts")
            self.create_timer(0.05, self.tick)

        def tick(self):
            try:
                if SIGNAL:
                    os.kill(os.getpid(), signal.SIGINT)
                    for _ in range(10_000_000):   # the handler raises at a bytecode here
                        pass
                raise RuntimeError("no signal arrived")
            except KeyboardInterrupt:
                raise RuntimeError("Unable to convert call argument '0' to Python object")

    sys.exit(run_node(Converts, "converts", args=["converts"]))
""")


def _run(mode: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", NODE, mode], capture_output=True,
                          text=True, timeout=120)


def test_error_caused_by_a_stop_signal_is_a_clean_stop():
    proc = _run("signal")
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr


def test_the_same_error_without_a_signal_surfaces():
    proc = _run("none")
    assert proc.returncode == 1, proc.stderr
    assert "RuntimeError: no signal arrived" in proc.stderr


def test_a_stop_signal_handled_late_in_the_teardown_does_not_cut_it_short():
    """The stop signal's Python handler raises once, at the next bytecode of the main thread:
    when rclpy's own handler has already ended the spin, that can be inside the teardown
    (seen under load: a node ended by the signal, exit -2). The teardown then runs again."""
    from rheo_shaping.nodes.spin import _teardown
    calls = []

    class Node:
        def destroy_node(self):
            calls.append("destroy")
            if len(calls) == 1:
                raise KeyboardInterrupt

    _teardown(Node())
    assert calls == ["destroy", "destroy"]


def test_a_stop_signal_in_rclpys_own_code_raises_nothing_once_rclpy_stops_the_node():
    # a KeyboardInterrupt raised in the executor's Task constructor left a half-built Task
    # whose __del__ printed a traceback at exit (CI, the gap watch stopped on a busy
    # machine); after rclpy.init, rclpy's own handler shuts the context down instead
    from rclpy.task import Task
    from rheo_shaping.nodes.spin import _StopSignal, in_rclpy
    frames = {}

    def handler():
        frames["rclpy"] = sys._getframe(1)           # Task.__call__, rclpy's code
    Task(handler)()
    ours = sys._getframe()
    assert in_rclpy(frames["rclpy"]) and not in_rclpy(ours) and not in_rclpy(None)
    before_init = _StopSignal()
    with pytest.raises(KeyboardInterrupt):           # before rclpy.init: no one else stops it
        before_init(signal.SIGINT, frames["rclpy"])
    stop = _StopSignal()
    stop.rclpy_stops = True
    stop(signal.SIGINT, frames["rclpy"])
    assert stop.received == signal.SIGINT
    in_ours = _StopSignal()
    in_ours.rclpy_stops = True
    with pytest.raises(KeyboardInterrupt):           # in this package's code: as before
        in_ours(signal.SIGTERM, ours)


def _frame(filename: str, back=None) -> SimpleNamespace:
    """A stand-in for an interrupted frame: what in_rclpy reads of one (f_code.co_filename,
    f_back)."""
    return SimpleNamespace(f_code=SimpleNamespace(co_filename=filename), f_back=back)


def test_a_stop_signal_in_the_standard_library_counts_for_the_code_that_called_it():
    # a signal landing in inspect or enum, called from a Task's constructor, is rclpy's: the
    # first frame out that is not the standard library's decides
    import inspect
    import enum
    import rclpy.task
    from rheo_shaping.nodes import spin
    ours = _frame(__file__)
    rclpys = _frame(rclpy.task.__file__, ours)
    assert spin.in_rclpy(_frame(inspect.__file__, _frame(enum.__file__, rclpys)))
    assert spin.in_rclpy(_frame("<frozen importlib._bootstrap>", rclpys))
    assert not spin.in_rclpy(_frame(inspect.__file__, ours))
    assert not spin.in_rclpy(_frame(inspect.__file__))      # the standard library alone
    # a package installed beneath the standard library's directory is not the library's
    beneath = f"{spin.STDLIB_DIR}/site-packages/somepkg/mod.py"
    assert not spin.in_rclpy(_frame(beneath, rclpys))
