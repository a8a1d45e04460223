"""Plain JSON from the package's results (a leaf: imports nothing of the package)."""
from __future__ import annotations

import math
from typing import Any


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float (NaN, inf) as None, through dicts, lists and
    tuples (JSON has no NaN; ``json.dump(..., allow_nan=False)`` then succeeds)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value
