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
