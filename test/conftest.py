"""Session-wide test set-up: which tests this virtualenv runs, and a private ROS 2 domain.

* ``--stage core|ros|all|auto`` (default ``auto``: ``all`` where rclpy can be imported, so
  ``colcon test`` in a ROS 2 environment runs every test, node tests included, and
  ``core`` elsewhere): test folders are split between the stages by
  ``_support/stages.py``, the one place that decides it (dev.py reads it too and passes
  the stage of each virtualenv).
* Every ROS process a test starts (and rclpy inside the test process) inherits
  ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (DDS discovery stays on this host) and a
  ``ROS_DOMAIN_ID`` of this session's own: ``python3 dev.py test`` claims one and passes
  it down; when pytest runs directly, a free id is claimed here the same way
  (``_support/domains.py``: a flock'ed lock file per id, held until the session ends).
* No test writes into the source tree: the session fails when the repository has untracked
  or ignored entries at its end that it lacked at its start (``_support/source_tree.py``);
  hypothesis keeps its example database and caches in the user's cache, not in
  ``.hypothesis/``.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from _support import source_tree
from _support.domains import claim_domain_id
from _support.stages import STAGES, stage_of

REPO = Path(__file__).resolve().parents[1]
#: The repository's untracked and ignored entries when the session started (None: no git).
_TREE: pytest.StashKey[set[str] | None] = pytest.StashKey()


def pytest_addoption(parser):
    parser.addoption("--stage", choices=(*STAGES, "all", "auto"), default="auto",
                     help="which tests to collect: core (ROS-free), ros, all, auto (the "
                          "default: all where rclpy imports, else core; "
                          "test/_support/stages.py)")


def _stage(config) -> str:
    stage = config.getoption("--stage")
    if stage == "auto":
        import importlib.util
        stage = "all" if importlib.util.find_spec("rclpy") is not None else "core"
    return stage


def pytest_ignore_collect(collection_path, config):
    stage = _stage(config)
    of = stage_of(collection_path)
    if stage == "all" or of is None or of == stage:
        return None
    return True


@pytest.fixture(scope="session")
def claim_ros_domain():
    """Claim another free ROS_DOMAIN_ID, held until the session ends: ``claim_ros_domain()``."""
    return claim_domain_id


def pytest_configure(config):
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if not os.environ.get("ROS_DOMAIN_ID"):
        os.environ["ROS_DOMAIN_ID"] = str(claim_domain_id())
    try:
        from hypothesis.configuration import set_hypothesis_home_dir
    except ImportError:
        return
    # its example database and caches, else .hypothesis/ in the working directory
    set_hypothesis_home_dir(source_tree.user_cache("hypothesis"))


def pytest_sessionstart(session):
    session.config.stash[_TREE] = source_tree.entries(REPO)


def pytest_sessionfinish(session, exitstatus):
    before = session.config.stash.get(_TREE, None)
    after = source_tree.entries(REPO) if before is not None else None
    if before is None or after is None:
        return
    new = source_tree.added(before, after)
    if new:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        text = ("a test wrote into the source tree (git status --porcelain --ignored):\n  "
                + "\n  ".join(new))
        if reporter is not None:
            reporter.write_line(text, red=True)
        if session.exitstatus == pytest.ExitCode.OK:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_report_header(config):
    return (f"stage {_stage(config)}; "
            f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')}")
