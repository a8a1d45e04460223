"""What a test run adds to the source tree (standard library only).

No test may write into the repository: ``colcon test`` runs pytest with the package's source
folder as its working directory, and a user's ``git status --porcelain --ignored`` must stay
as it was.  test/conftest.py takes :func:`entries` when the session starts and ends, and fails
the session on what :func:`added` finds.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

#: Written by the tools, not by a test: Python's bytecode (PYTHONDONTWRITEBYTECODE=1 stops
#: it) and pytest's own cache (``colcon test`` moves it to its build folder).
TOOL_CACHES = ("__pycache__", ".pytest_cache")


def entries(repo: Path) -> set[str] | None:
    """The untracked and ignored entries of ``repo`` (``git status --porcelain --ignored``
    lines), or None where ``repo`` is not a git work tree (a release tarball)."""
    try:
        proc = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--ignored"],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                              timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return None
    if proc.returncode != 0:
        return None
    return {line for line in proc.stdout.splitlines() if line[:2] in ("??", "!!")}


def added(before: set[str], after: set[str]) -> list[str]:
    """The entries of ``after`` that ``before`` lacks, but the tools' own caches, sorted."""
    return sorted(e for e in after - before
                  if not any(part in TOOL_CACHES for part in Path(e[3:]).parts))


def user_cache(name: str) -> str:
    """A folder [path] of this user's cache for the tests' own caches (``name``: the tool),
    outside the source tree: ``$XDG_CACHE_HOME/rheo_shaping/tests/NAME``."""
    import os
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return str(Path(base) / "rheo_shaping" / "tests" / name)
