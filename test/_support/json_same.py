"""JSON objects compared for the JSON-unchanged tests: the same keys, types and strings
everywhere, numbers within a relative 1e-6 (two numpy builds' last digits)."""
from __future__ import annotations

import math


def differences(a, b, where: str = "$") -> list[str]:
    """Where ``a`` and ``b`` (parsed JSON) differ; empty when they are the same."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{where}: keys {sorted(set(a) ^ set(b))} on one side only"] \
            if set(a) != set(b) else []
        for k in sorted(set(a) & set(b)):
            out += differences(a[k], b[k], f"{where}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items against {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b))
                for d in differences(x, y, f"{where}[{i}]")]
    num = (int, float)
    if isinstance(a, num) and isinstance(b, num) and not isinstance(a, bool) \
            and not isinstance(b, bool):
        same = (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-6,
                                                                 abs_tol=1e-12)
        return [] if same else [f"{where}: {a!r} against {b!r}"]
    return [] if (type(a) is type(b) and a == b) else [f"{where}: {a!r} against {b!r}"]
