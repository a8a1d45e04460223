"""The one place that splits the test suite between the two virtualenvs (standard library
only: dev.py reads it).

Tests in :data:`ROS_FOLDERS` need ROS 2 (rclpy, message packages, colcon) and run in
``.venv``; every other folder of ``test/`` is ROS-free and runs in ``.venv-core``, where
dev.py first checks that ``import rclpy`` fails.
"""
from __future__ import annotations

from pathlib import Path

TEST_DIR = Path(__file__).resolve().parents[1]

#: test/ folders whose tests need ROS 2.
ROS_FOLDERS = ("nodes", "package")

STAGES = ("core", "ros")


def stage_of(path: str | Path) -> str | None:
    """``"ros"`` or ``"core"`` for a path inside test/ (a folder or a test file), None for
    test/ itself, test/_support or a path outside test/."""
    p = Path(path).resolve()
    try:
        rel = p.relative_to(TEST_DIR)
    except ValueError:
        return None
    if not rel.parts or rel.parts[0].startswith("_") or rel.parts[0] == "conftest.py":
        return None
    return "ros" if rel.parts[0] in ROS_FOLDERS else "core"


def folders(stage: str) -> list[Path]:
    """The test folders of ``stage``."""
    return sorted(d for d in TEST_DIR.iterdir()
                  if d.is_dir() and stage_of(d) == stage)
