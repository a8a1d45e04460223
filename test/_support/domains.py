"""A ROS_DOMAIN_ID of this run's own (standard library only: dev.py uses it too).

A lock file per id under the temp dir is held (flock) for the lifetime of the claiming
process; child processes inherit the id through the environment, so concurrent runs on
this machine do not see each other's nodes.
"""
from __future__ import annotations

import fcntl
import random
import tempfile
from pathlib import Path

_locks: list = []  # kept open while the process runs: its claims


def claim_domain_id() -> int:
    """Pick a ROS_DOMAIN_ID in 1-100 that no other concurrent run on this machine holds."""
    lock_dir = Path(tempfile.gettempdir()) / "rheo_shaping-ros-domains"
    lock_dir.mkdir(exist_ok=True)
    ids = list(range(1, 101))  # 0 is the default everyone else uses
    start = random.randrange(len(ids))
    for i in ids[start:] + ids[:start]:
        fh = open(lock_dir / f"{i}.lock", "w")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        _locks.append(fh)
        return i
    return random.choice(ids)
