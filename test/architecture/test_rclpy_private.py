"""rclpy's private attributes are touched in one module only (rheo_shaping/nodes/
rclpy_private.py): the time source, the parameter overrides, a lifecycle node's state
machine.  Read from the source (ast), so it runs in either virtualenv."""
from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[2] / "rheo_shaping"
#: The private attributes of rclpy's objects this package needs (and where they may be used).
PRIVATE = {"_time_source", "_clock_sub", "_subscribe_to_clock_topic", "_parameter_overrides",
           "_state_machine"}
ALLOWED = PKG / "nodes" / "rclpy_private.py"


def test_rclpy_private_attributes_only_in_one_module():
    found = []
    for path in sorted(PKG.rglob("*.py")):
        if path == ALLOWED:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr in PRIVATE:
                found.append(f"{path.relative_to(PKG.parent)}:{node.lineno} .{node.attr}")
            if (isinstance(node, ast.Call) and getattr(node.func, "id", "") == "getattr"
                    and len(node.args) > 1 and isinstance(node.args[1], ast.Constant)
                    and node.args[1].value in PRIVATE):
                found.append(f"{path.relative_to(PKG.parent)}:{node.lineno} "
                             f"getattr {node.args[1].value}")
    assert found == [], found
    uses = {n.attr for n in ast.walk(ast.parse(ALLOWED.read_text()))
            if isinstance(n, ast.Attribute)}
    assert PRIVATE <= uses          # the module holds each of them (the list is not stale)
