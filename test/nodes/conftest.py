"""Fixtures of the ROS 2 node tests (the helpers live in test/_support/ros.py)."""
from _support.ros import procs, ros  # noqa: F401  (fixtures)
