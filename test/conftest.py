"""Session-wide test environment: keep ROS 2 traffic on this machine and private.

Every ROS process a test starts (and rclpy inside the test process) inherits:

* ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``: DDS discovery stays on this host;
* ``ROS_DOMAIN_ID``: one per test session, so concurrent runs do not see each
  other's nodes. ``python3 dev.py test`` claims one and passes it down; when
  pytest is run directly, a free id is claimed here the same way (a flock'ed
  lock file per id in the temp dir, held until the session ends).

Harmless where ROS is not installed (test/core runs in .venv-core).
"""
from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest


def _dev():
    """dev.py, loaded once for the session: its module holds every claimed lock file open."""
    if _dev.module is None:
        spec = importlib.util.spec_from_file_location("rheo_dev", Path(__file__).resolve().parents[1] / "dev.py")
        _dev.module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(_dev.module)
    return _dev.module


_dev.module = None


def _claim_domain_id() -> int:
    """dev.py's lock-file claim of a free ROS_DOMAIN_ID (one implementation for both)."""
    return _dev().claim_domain_id()


@pytest.fixture(scope="session")
def claim_ros_domain():
    """Claim another free ROS_DOMAIN_ID, held until the session ends: ``claim_ros_domain()``."""
    return _claim_domain_id


def pytest_configure(config):
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if not os.environ.get("ROS_DOMAIN_ID"):
        os.environ["ROS_DOMAIN_ID"] = str(_claim_domain_id())


def pytest_report_header(config):
    return (f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')}")
