"""The suite's type check: mypy with setup.cfg's [mypy] settings over parts of the package
(standard library only).

mypy's cache lives in the user's cache ($XDG_CACHE_HOME/rheo_shaping/tests/mypy/
<checkout>-<virtualenv>/, not in the source tree), one per checkout and virtualenv (two
checkouts must not share one: mypy's cache is not locked), so a second run only re-checks
what changed.
"""
from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest

from _support.source_tree import user_cache

ROOT = Path(__file__).resolve().parents[2]


def require_mypy_clean(names: tuple[str, ...], extra: tuple[str, ...] = ()) -> None:
    """Fail the test with mypy's report unless mypy finds no error in ``names`` (paths
    under rheo_shaping/) and ``extra`` (paths from the repository's root), each of which
    must exist."""
    paths = [str(Path("rheo_shaping") / name) for name in names] + list(extra)
    for path in paths:
        assert (ROOT / path).exists(), f"{path}: listed to be type-checked but missing"
    checkout = hashlib.sha256(str(ROOT).encode()).hexdigest()[:12]
    cache = Path(user_cache("mypy")) / f"{checkout}-{Path(sys.prefix).name}"
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", "setup.cfg", "--cache-dir", str(cache),
         *paths], cwd=ROOT, capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.fail(f"mypy (exit {proc.returncode}):\n{proc.stdout}{proc.stderr}", pytrace=False)
