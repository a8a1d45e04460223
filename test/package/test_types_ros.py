"""The type check of the ROS side: mypy over nodes/ and cli/ with setup.cfg's [mypy]
settings, in the ros stage (where rclpy, whose types they are checked against, imports;
the message packages ship none: setup.cfg names them).  The core's:
test/architecture/test_types.py.

Each mixin of a node is typed against its host, a :class:`typing.Protocol` in
rheo_shaping/nodes/hosts.py; mypy checks the mixin's code and the node against it.
"""
from __future__ import annotations

import pytest

from _support.typecheck import require_mypy_clean

#: What is checked, under rheo_shaping/ (with what they import of the core).
CHECKED = ("nodes", "cli")


def test_nodes_and_cli_type_check():
    """mypy finds no error in nodes/ and cli/."""
    pytest.importorskip("rclpy")
    require_mypy_clean(CHECKED)
