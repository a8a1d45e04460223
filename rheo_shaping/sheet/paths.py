"""Tool paths: a prescribed motion of the tool's reference point [m] against time [s]
(what :func:`rheo_shaping.sheet.simulation.run_scenario` drives the sheet with)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


class ToolPath(Protocol):
    """A prescribed tool motion: reference point [m] against time [s]."""

    @property
    def duration(self) -> float: ...

    def position(self, t: float) -> np.ndarray: ...

    def knots(self) -> np.ndarray: ...


@dataclass(frozen=True)
class PolylinePath:
    """Piecewise-linear tool motion through ``points`` (K, 2) at ``times`` (K,)."""

    times: np.ndarray
    points: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def position(self, t: float) -> np.ndarray:
        return np.array([np.interp(t, self.times, self.points[:, 0]),
                         np.interp(t, self.times, self.points[:, 1])])

    def knots(self) -> np.ndarray:
        return np.asarray(self.times, dtype=float)


__all__ = ["PolylinePath", "ToolPath"]
