"""docs/architecture.md against the code: every module and name its table of subpackages
gives exists where it says (read from the source; no ROS).  What each subpackage may import
is checked by test_layering.py."""
from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "rheo_shaping"

ROW = re.compile(r"^\| `(\w+)/` \| (.*) \| (.*) \|$")


def _rows() -> list[tuple[str, str, str]]:
    text = (ROOT / "docs" / "architecture.md").read_text()
    return [m.groups() for m in map(ROW.match, text.splitlines()) if m]


def _defined(unit: Path) -> set[str]:
    """Module names (files and packages) and top-level names defined anywhere in ``unit``."""
    names = {p.stem for p in unit.rglob("*.py")} | {p.name for p in unit.rglob("*") if p.is_dir()}
    for path in unit.rglob("*.py"):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                names.add(node.name)
                names |= {n.name for n in node.body
                          if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
                names |= {n.target.id for n in node.body          # dataclass fields
                          if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)}
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for t in targets:
                    names |= {n.id for n in ast.walk(t) if isinstance(n, ast.Name)}
    return names


def test_every_name_in_the_table_exists_in_its_subpackage():
    """A name is its subpackage's (a module, class, function, field or constant there), or
    one the row takes from elsewhere in the package (``ToolParams``), or a library
    (``rosbags``); file names (``scenario.yaml``) are not checked."""
    import importlib.util
    rows = _rows()
    assert len(rows) >= 12, "the table of subpackages was not found"
    everywhere = _defined(PKG)
    missing = []
    for unit, owns, _ in rows:
        defined = _defined(PKG / unit)
        for token in re.findall(r"`([A-Za-z_][\w.]*)`", owns):
            if re.search(r"\.(yaml|json|py|csv|md)$", token):
                continue
            parts = token.split(".")
            if all(p in defined for p in parts):
                continue
            if len(parts) == 1 and (token in everywhere
                                    or importlib.util.find_spec(token) is not None):
                continue
            missing.append(f"{unit}/: `{token}`")
    assert not missing, "named in docs/architecture.md but not in the code: " + ", ".join(missing)


VALIDATION_ROW = re.compile(r"^\| `rheo_shaping_validation/(\w+)(/|\.py)` \| (.*) \| (.*) \|$")


def test_every_name_in_the_validation_table_exists_in_its_module():
    """The same for the validation package's table: a name is its module's (or package's),
    or one defined elsewhere in the validation or the product."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    rows = [m.groups() for m in map(VALIDATION_ROW.match, text.splitlines()) if m]
    assert {r[0] for r in rows} >= {"worlds", "benchmark", "gapwatch_campaign"}
    val = ROOT / "rheo_shaping_validation"
    everywhere = _defined(val) | _defined(PKG)
    missing = []
    for unit, kind, owns, _ in rows:
        path = val / unit if kind == "/" else val / f"{unit}.py"
        assert path.exists(), f"docs/architecture.md names {path.name}, which is not there"
        defined = _defined(path) if path.is_dir() else _defined_file(path)
        for token in re.findall(r"`([A-Za-z_][\w.]*)`", owns):
            if re.search(r"\.(yaml|json|py|csv|md)$", token):
                continue
            parts = token.split(".")
            if all(p in defined for p in parts) or (len(parts) == 1 and token in everywhere):
                continue
            missing.append(f"{unit}: `{token}`")
    assert not missing, "named in docs/architecture.md but not in the code: " + ", ".join(missing)


def _defined_file(path: Path) -> set[str]:
    """:func:`_defined` of one module."""
    names = {path.stem}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
    return names
