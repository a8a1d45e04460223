"""rclpy's logger keeps one severity per call site (function, file, line, bytecode index) and
raises ``ValueError: Logger severity cannot be changed between calls`` when the same call
logs at another severity: ``(log.info if ok else log.warning)(text)`` or ``log = a.info if
ok else a.warning; log(text)`` is a traceback waiting for the second severity (the closed
loop's planner died of it under a CPU hog, a dropped re-plan's WARN then an INFO)."""
from __future__ import annotations

import ast
from pathlib import Path

import rheo_shaping

SEVERITIES = {"debug", "info", "warning", "warn", "error", "fatal"}


def _is_log_method(node: ast.AST) -> bool:
    return isinstance(node, ast.Attribute) and node.attr in SEVERITIES


def _chooses_severity(node: ast.AST) -> bool:
    return (isinstance(node, ast.IfExp) and _is_log_method(node.body)
            and _is_log_method(node.orelse))


def offenders(source: str, name: str) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(source, name)):
        if isinstance(node, ast.Call) and _chooses_severity(node.func):
            out.append(f"{name}:{node.lineno}: a call whose severity is chosen at run time")
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None \
                and _chooses_severity(node.value):
            out.append(f"{name}:{node.lineno}: a logger method chosen at run time, called "
                       f"from one site")
    return out


def test_the_rule_sees_both_forms():
    assert offenders("(log.info if ok else log.warning)(text)\n", "a")
    assert offenders("log = a.info if ok else a.warning\nlog(text)\n", "b")
    assert not offenders("if ok:\n    log.info(text)\nelse:\n    log.warning(text)\n", "c")


def test_no_call_site_of_the_package_changes_its_severity():
    root = Path(rheo_shaping.__file__).parent
    found = [o for path in sorted(root.rglob("*.py"))
             for o in offenders(path.read_text(), str(path.relative_to(root.parent)))]
    assert not found, "\n".join(found)
