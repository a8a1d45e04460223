"""The lint the suite enforces: flake8 (from PyPI) over the package, the tests, the
benchmarks and dev.py with setup.cfg's [flake8] (line length 99, as ament_flake8)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_flake8_is_clean():
    proc = subprocess.run([sys.executable, "-m", "flake8", "rheo_shaping", "test", "benchmarks",
                           "dev.py", "launch"], cwd=REPO, capture_output=True, text=True)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-6000:]


def test_flake8_config_is_ament_flake8s_line_length():
    import configparser
    cfg = configparser.ConfigParser()
    cfg.read(REPO / "setup.cfg")
    assert cfg["flake8"]["max-line-length"] == "99"
