"""Every module of the product and of the validation package is short: at most 400 lines
(docs/architecture.md)."""
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LIMIT = 400
MODULES = sorted(p for pkg in ("rheo_shaping", "rheo_shaping_validation")
                 for p in (ROOT / pkg).rglob("*.py"))


def test_the_modules_are_found():
    assert len(MODULES) > 100


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_module_is_over_400_lines(path):
    n = len(path.read_text().splitlines())
    assert n <= LIMIT, f"{path.relative_to(ROOT)}: {n} lines (at most {LIMIT})"
