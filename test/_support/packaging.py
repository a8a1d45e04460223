"""The repository's packaging files read as data (standard library only)."""
from __future__ import annotations

import ast
from pathlib import Path

#: The repository root (this file is test/_support/packaging.py).
REPO = Path(__file__).resolve().parents[2]


def setup_kwargs() -> dict[str, ast.expr]:
    """The keyword arguments of setup.py's ``setup(...)`` call, as unevaluated expressions."""
    tree = ast.parse((REPO / "setup.py").read_text())
    call = next(n for n in ast.walk(tree)
                if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "setup")
    return {kw.arg: kw.value for kw in call.keywords if kw.arg is not None}
