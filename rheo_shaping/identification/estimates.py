"""An estimated constant with its standard error and 95 % confidence interval."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..jsonable import json_safe


@dataclass(frozen=True)
class Estimate:
    """``value`` in ``unit``; ``se`` its standard error; ``ci95 = (lo, hi)``.

    ``None`` stands for "not determined by these data" (a value not
    identifiable, an error that cannot be computed, or an unbounded side of an
    interval).  ``note`` says how it was obtained or why it is missing.
    """

    value: float | None
    se: float | None
    ci95: tuple[float | None, float | None] | None
    unit: str
    note: str = ""

    @classmethod
    def missing(cls, unit: str, note: str) -> "Estimate":
        return cls(None, None, None, unit, note)

    def as_dict(self) -> dict:
        """JSON-ready: non-finite numbers become ``None``."""
        ci = None if self.ci95 is None else [_finite(self.ci95[0]), _finite(self.ci95[1])]
        return {"value": _finite(self.value), "se": _finite(self.se), "ci95": ci,
                "unit": self.unit, "note": self.note}

    def relative_error(self, truth: float) -> float:
        """(value - truth)/truth, for comparisons with known constants."""
        if self.value is None:
            raise ValueError(f"no relative error of an estimate without a value "
                             f"({self.note or 'not determined'})")
        return (self.value - truth) / truth


def _finite(x: float | None) -> float | None:
    return None if x is None else json_safe(float(x))


def t_quantile(dof: int, level: float = 0.95) -> float:
    """Two-sided Student-t quantile for ``dof`` degrees of freedom (normal when dof is large)."""
    if dof <= 0:
        return math.inf
    from scipy import stats        # lazy: keeps `rheo-shaping --help` fast
    return float(stats.t.ppf(0.5 + level / 2.0, dof))


def symmetric(value: float, se: float | None, unit: str, dof: int, note: str = "",
              lower: float | None = None) -> Estimate:
    """``value +- t * se``, the lower end clipped at ``lower`` (a physical bound)."""
    if se is None or not math.isfinite(se):
        return Estimate(value, None, None, unit, note)
    q = t_quantile(dof)
    lo, hi = value - q * se, value + q * se
    if lower is not None:
        lo = max(lo, lower)
    return Estimate(value, se, (lo, hi), unit, note)
