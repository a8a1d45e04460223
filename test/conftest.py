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
"""
from __future__ import annotations

import os

import pytest

from _support.domains import claim_domain_id
from _support.stages import STAGES, stage_of


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


def pytest_report_header(config):
    return (f"stage {_stage(config)}; "
            f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')}")
