"""One cell for every node: a fingerprint of every cell parameter (docs/safety.md, "One cell").

The simulator publishes its cell on ``/shaping/cell`` (latched) as :func:`cell_message`;
the planner and the monitor compare it with their own (:func:`cell_mismatch`) and refuse to
run on a cell that differs, naming each parameter that differs and both values.  A slip in
one node's parameters (``-p movement.speed:=0.005`` given to the planner only) would
otherwise let the planner drive a faster plan than the monitor's threshold was set for.
"""
from __future__ import annotations

import hashlib
import json
from typing import Any

from .cell import CellParams
from .schema import to_flat
from .wire import load_json


def cell_values(cell: CellParams) -> dict[str, Any]:
    """Every cell parameter by its dotted name (``movement.speed``), JSON-able values."""
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in sorted(to_flat(cell).items())}


def cell_fingerprint(cell: CellParams) -> str:
    """A 16-hex-digit digest of every cell parameter (equal cells, equal fingerprints)."""
    text = json.dumps(cell_values(cell), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cell_message(cell: CellParams) -> str:
    """What the simulator publishes on ``/shaping/cell``: the fingerprint and the values."""
    return json.dumps({"fingerprint": cell_fingerprint(cell), "values": cell_values(cell)},
                      sort_keys=True, separators=(",", ":"))


#: Differences named in one reason at the most (the rest are counted).
MAX_NAMED = 4


def cell_mismatch(own: CellParams, message: str, own_name: str = "this node",
                  other_name: str = "the simulator") -> str:
    """Why ``own`` is not the cell of ``message`` (a :func:`cell_message`); "" when equal.

    A message that is not a cell message is a mismatch too (named as such)."""
    try:
        data = load_json(message, max_depth=3)
        fingerprint, values = data["fingerprint"], data["values"]
        if not isinstance(values, dict) or not isinstance(fingerprint, str):
            raise TypeError
    except (ValueError, KeyError, TypeError):          # WireError is a ValueError
        return f"the cell message of {other_name} is not a cell fingerprint: {message[:80]!r}"
    mine = cell_values(own)
    if fingerprint == cell_fingerprint(own) and values == mine:
        return ""
    diff = [k for k in sorted(set(mine) | set(values)) if mine.get(k) != values.get(k)]
    if not diff:                      # same values, another digest: another version's rule
        return (f"the cell fingerprint of {other_name} ({fingerprint}) differs from "
                f"{own_name}'s ({cell_fingerprint(own)})")
    named = ", ".join(f"{k} = {mine.get(k, 'absent')} ({own_name}) vs "
                      f"{values.get(k, 'absent')} ({other_name})" for k in diff[:MAX_NAMED])
    more = f" and {len(diff) - MAX_NAMED} more" if len(diff) > MAX_NAMED else ""
    return f"the cell differs from {other_name}'s: {named}{more}"
