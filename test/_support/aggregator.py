"""diagnostic_aggregator's GenericAnalyzer grouping, as its documentation states it, applied
to status names (there is no diagnostic_aggregator wheel to run here): a status belongs to
an analyzer when its name equals one of ``name``, starts with one of ``startswith``, or
contains one of ``contains``; the first analyzer that matches takes it."""
from __future__ import annotations

from pathlib import Path

import yaml


def analyzers(path: Path) -> dict[str, dict]:
    """The GenericAnalyzers of an aggregator params file, by their key."""
    params = yaml.safe_load(Path(path).read_text())["analyzers"]["ros__parameters"]
    return {k: v for k, v in params.items()
            if isinstance(v, dict) and v.get("type") == "diagnostic_aggregator/GenericAnalyzer"}


def _as_list(value) -> list[str]:
    return [value] if isinstance(value, str) else list(value or [])


def group(names, path: Path) -> dict[str, set[str]]:
    """{analyzer key: the status names it takes}; names no analyzer takes under ``""``."""
    out: dict[str, set[str]] = {}
    found = analyzers(path)
    for name in names:
        key = next((k for k, a in found.items()
                    if name in _as_list(a.get("name"))
                    or any(name.startswith(p) for p in _as_list(a.get("startswith")))
                    or any(c in name for c in _as_list(a.get("contains")))), "")
        out.setdefault(key, set()).add(name)
    return out
