"""The type check: mypy over the core subpackages and the validation package, with
setup.cfg's [mypy] settings.

Runs in the core stage and the noble stage, so the annotations hold against numpy 2's
stubs (and numba's, which 0.68 ships) and against numpy 1.26's (noble's numba 0.59 ships
none: its names are Any there).  mypy's cache lives in the user's cache
($XDG_CACHE_HOME/rheo_shaping/tests/mypy/<checkout>-<virtualenv>/, not in the source tree),
one per checkout and virtualenv, so a second run only re-checks what changed.
"""
from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest

from _support.source_tree import user_cache

ROOT = Path(__file__).resolve().parents[2]

#: What is checked, under rheo_shaping/: the core but nodes/ and cli/ (the ROS side).
CHECKED = ("params", "material", "identification", "sheet", "planning", "safety", "records",
           "study", "diagnosis", "gapwatch", "adaptive", "parallel.py", "units.py",
           "jsonable.py", "_lazy.py")
#: Checked whole beside it: the validation package (its worlds, benchmark, campaigns).
VALIDATION = "rheo_shaping_validation"


def test_core_subpackages_type_check():
    """mypy finds no error in the checked part of the core."""
    paths = [str(Path("rheo_shaping") / name) for name in CHECKED] + [VALIDATION]
    for path in paths:
        assert (ROOT / path).exists(), f"{path}: listed in CHECKED but missing"
    # mypy's cache outside the source tree (no test writes there: test/conftest.py), one per
    # checkout and virtualenv (two checkouts must not share one: mypy's cache is not locked)
    checkout = hashlib.sha256(str(ROOT).encode()).hexdigest()[:12]
    cache = Path(user_cache("mypy")) / f"{checkout}-{Path(sys.prefix).name}"
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", "setup.cfg", "--cache-dir", str(cache),
         *paths], cwd=ROOT, capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.fail(f"mypy (exit {proc.returncode}):\n{proc.stdout}{proc.stderr}", pytrace=False)
