"""Session-wide test set-up: which tests this virtualenv runs, and a private ROS 2 domain.

* ``--stage core|ros|all`` (default ``core``, so a bare ``pytest`` or ``colcon test`` runs
  the ROS-free tests): test folders are split between the stages by
  ``_support/stages.py``, the one place that decides it (dev.py reads it too).
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
    parser.addoption("--stage", choices=(*STAGES, "all"), default="core",
                     help="which tests to collect: core (ROS-free, the default), ros, all "
                          "(test/_support/stages.py)")


def pytest_ignore_collect(collection_path, config):
    stage = config.getoption("--stage")
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
    return (f"stage {config.getoption('--stage')}; "
            f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')}")
