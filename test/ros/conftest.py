"""Fixtures of the ROS 2 tests (the helpers live in rosutil.py)."""
from rosutil import procs, ros  # noqa: F401  (fixtures)
