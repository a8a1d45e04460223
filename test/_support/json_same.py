"""JSON objects compared for the JSON-unchanged tests: the same keys, types and strings
everywhere, numbers within a relative 1e-6 (the last digits of one numpy build's linear
algebra run twice), or only as numbers (``numbers=False``: another numpy and BLAS build,
whose rounding moves a diagnosis's figures by up to 1e-4 relative)."""
from __future__ import annotations

import math


def differences(a, b, where: str = "$", numbers: bool = True) -> list[str]:
    """Where ``a`` and ``b`` (parsed JSON) differ; empty when they are the same."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{where}: keys {sorted(set(a) ^ set(b))} on one side only"] \
            if set(a) != set(b) else []
        for k in sorted(set(a) & set(b)):
            out += differences(a[k], b[k], f"{where}.{k}", numbers)
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items against {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b))
                for d in differences(x, y, f"{where}[{i}]", numbers)]
    num = (int, float)
    if isinstance(a, num) and isinstance(b, num) and not isinstance(a, bool) \
            and not isinstance(b, bool):
        same = (not numbers or (math.isnan(a) and math.isnan(b))
                or math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-12))
        return [] if same else [f"{where}: {a!r} against {b!r}"]
    return [] if (type(a) is type(b) and a == b) else [f"{where}: {a!r} against {b!r}"]
