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

import fcntl
import os
import random
import tempfile
from pathlib import Path

_domain_lock = None


def _claim_domain_id() -> int:
    global _domain_lock
    lock_dir = Path(tempfile.gettempdir()) / "rheo_shaping-ros-domains"
    lock_dir.mkdir(exist_ok=True)
    ids = list(range(1, 101))
    start = random.randrange(len(ids))
    for i in ids[start:] + ids[:start]:
        fh = open(lock_dir / f"{i}.lock", "w")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        _domain_lock = fh
        return i
    return random.choice(ids)


def pytest_configure(config):
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if not os.environ.get("ROS_DOMAIN_ID"):
        os.environ["ROS_DOMAIN_ID"] = str(_claim_domain_id())


def pytest_report_header(config):
    return (f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')}")
