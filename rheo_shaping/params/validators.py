"""The input checks of the core, in one place: each names the quantity, shows the value
and says what was expected (``k1 [N/m] = -3.0: expected a positive finite number``),
and raises :class:`ValueError`; nothing is clamped.  Imports nothing of the package.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

#: A point (x, z) [m] as callers hold it: a pair of numbers or a (2,) array.
PointLike = Sequence[float] | np.ndarray


def show(value: Any) -> str:
    """``repr`` of a value, numpy scalars shown as plain numbers."""
    if isinstance(value, np.generic):
        value = value.item()
    return repr(value)


def check_number(name: str, value: Any) -> float:
    """``float(value)``, or :class:`ValueError` if it is no number."""
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {show(value)}: expected a number") from None


def check_finite(name: str, value: Any, *, positive: bool = False,
                 non_negative: bool = False) -> float:
    """``float(value)`` if it is finite (and > 0 / >= 0 when asked)."""
    if positive:
        return check_positive(name, value)
    if non_negative:
        return check_non_negative(name, value)
    v = check_number(name, value)
    if not math.isfinite(v):
        raise ValueError(f"{name} = {show(value)}: expected a finite number")
    return v


def check_positive(name: str, value: Any, allow_inf: bool = False) -> float:
    """``float(value)`` if it is a positive number (``inf`` only when allowed): NaN, zero,
    negative numbers and non-numbers are refused."""
    expected = "a number > 0 or inf" if allow_inf else "a finite number > 0"
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {show(value)}: expected {expected}") from None
    if math.isnan(v) or v <= 0.0 or (math.isinf(v) and not allow_inf):
        raise ValueError(f"{name} = {show(value)}: expected {expected}")
    return v


def check_non_negative(name: str, value: Any) -> float:
    """``float(value)`` if it is a finite number >= 0."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {show(value)}: expected a finite number >= 0") from None
    if not math.isfinite(v) or v < 0.0:
        raise ValueError(f"{name} = {show(value)}: expected a finite number >= 0")
    return v


def check_point(name: str, p: PointLike) -> np.ndarray:
    """A point (x, z) [m] as a (2,) array of finite numbers."""
    try:
        arr = np.asarray(p, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        arr = np.array([math.nan])
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} = {show(p)}: expected two finite numbers (x, z)")
    return arr


def check_time_step(dt: Any) -> None:
    """Refuse time steps ``dt`` [s] that are not positive and finite (scalar or array)."""
    if np.ndim(dt) == 0:
        if not 0.0 < dt < np.inf:   # also False for NaN
            raise ValueError(f"time step dt [s] = {show(dt)}: expected a positive finite number")
        return
    d = np.asarray(dt, dtype=float)
    bad = ~((d > 0.0) & np.isfinite(d))
    if bad.any():
        raise ValueError(
            f"time step dt [s] = {show(d[bad].flat[0])}: expected positive finite numbers")
