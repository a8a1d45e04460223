"""``rheo-shaping cell``: the three nodes in one process, the main job of dev.py."""
from __future__ import annotations

import json
import subprocess

import pytest

pytest.importorskip("rclpy")


from rheo_shaping.planning.movement import run_movement  # noqa: E402

from _support.ros import BIN  # noqa: E402
from _support.cells import base_cell  # noqa: E402


def _run(*args, timeout=120):
    return subprocess.run([str(BIN / "rheo-shaping"), "cell", *args], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, timeout=timeout)


def test_cell_runs_the_default_movement_4_and_matches_the_core():
    proc = _run("--json")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    cell = base_cell()
    assert out["movement"] == cell.movement.number == 4
    offline = run_movement(cell)
    assert out["finished"] and not out["aborted"]
    assert out["F_max"] == pytest.approx(offline.F_max, rel=0.02)
    assert out["delta"] == pytest.approx(offline.delta, abs=0.2e-3)
    assert out["SF"] == pytest.approx(cell.material.F_break / out["F_max"])


def test_cell_prints_progress_and_the_figures():
    proc = _run("--movement", "2", "--compare")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    text = proc.stdout
    assert "t =   10.0 / 120 s, ETA" in text and "F_max =" in text
    assert "SF    =" in text and "Delta =" in text
    assert "offline (core, same plan)" in text


def test_cell_refuses_bad_parameters(tmp_path):
    bad_cell = tmp_path / "bad_cell.yaml"
    bad_cell.write_text("/**:\n  ros__parameters:\n    material:\n      k1: -1.0\n")
    proc = _run("--params", str(bad_cell))
    assert proc.returncode == 2
    assert "material.k1" in proc.stderr and "-1.0" in proc.stderr and "(0, 1e+06]" in proc.stderr
    bad_node = tmp_path / "bad_node.yaml"
    bad_node.write_text("monitor:\n  ros__parameters:\n    abort_ratio: 1.5\n")
    proc = _run("--params", str(bad_node))
    assert proc.returncode == 2
    assert "abort_ratio" in proc.stderr and "1.5" in proc.stderr and "[0, 0.99]" in proc.stderr
