"""A signal at any moment of a node's start-up (imports, the kernel's loading, rclpy.init,
construction, first spins) ends it with exit code 0 and no traceback: a short run of
benchmarks/early_signals.py (the benchmark itself sends 50 per node)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "early_signals.py"


def test_early_signals_end_every_node_cleanly():
    proc = subprocess.run([sys.executable, str(SCRIPT), "--runs", "5", "--seed", "3", "--json"],
                          capture_output=True, text=True, timeout=600)
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["runs"] == 15
    assert summary["tracebacks"] == 0 and summary["nonzero_exits"] == 0, summary["failures"]
    assert proc.returncode == 0


BIN = Path(sys.executable).parent
NODES = ("simulator", "planner", "monitor")


def test_the_launcher_starts_python_with_sigint_and_sigterm_blocked(tmp_path):
    """The node executable's shell part (setup.py's LAUNCHER) starts its interpreter with
    SIGINT and SIGTERM blocked: here a stand-in ``python3`` that reports its mask."""
    import os
    import signal
    launcher = tmp_path / "monitor"
    stand_in = tmp_path / "python3"
    text = (BIN / "monitor").read_text()
    baked = next(line for line in text.splitlines() if line.startswith("py="))
    launcher.write_text(text.replace(baked, f"py={stand_in}", 1))
    stand_in.write_text("#!/bin/sh\nexec grep SigBlk /proc/self/status\n")
    for f in (launcher, stand_in):
        os.chmod(f, 0o755)
    out = subprocess.run([str(launcher)], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0, out.stderr
    mask = int(out.stdout.split()[1], 16)
    for sig in (signal.SIGINT, signal.SIGTERM):
        assert mask >> (sig - 1) & 1, f"{sig.name} not blocked: SigBlk {out.stdout.strip()}"


@pytest.mark.parametrize("exe", NODES)
@pytest.mark.parametrize("how", ("launcher", "interpreter"))
@pytest.mark.parametrize("entry", ("default", "ignored"))
def test_a_signal_pending_at_start_ends_the_node_cleanly(exe, how, entry):
    """A SIGINT that comes while the node starts ends it with exit 0 and no traceback.  Here it
    is blocked from before the exec, so it is pending whatever the timing: the launcher's shell
    hands it on, still pending, to Python (its exec, no child before it), and the interpreter
    holds it until the node's handler is in place.  ``ignored``: the node starts with SIGINT
    ignored, as a background job of a script does, where the shell's trap cannot take it."""
    import signal

    def child():
        signal.signal(signal.SIGINT, signal.SIG_DFL if entry == "default" else signal.SIG_IGN)
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})

    cmd = [str(BIN / exe)] if how == "launcher" else [sys.executable, str(BIN / exe)]
    p = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, start_new_session=True,
                         preexec_fn=child)
    p.send_signal(signal.SIGINT)
    try:
        out, _ = p.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        p.kill()
        out, _ = p.communicate()
        pytest.fail(f"{exe} did not end on a pending SIGINT:\n{out[-2000:]}")
    assert p.returncode == 0 and "Traceback" not in out, (p.returncode, out[-2000:])
    if how == "interpreter" or entry == "ignored":   # else the shell's trap may take it first
        assert "interrupted while starting" in out
