"""The trend of the largest tension: the monitor's optional early abort (``trend_abort``,
docs/safety.md) predicts the threshold from it."""
from __future__ import annotations

import math
from collections import deque

import numpy as np


class TensionTrend:
    """The least-squares slope [N/s] of the largest tension over the last ``window`` seconds
    of the cell's clock; ``rate`` is nan until ``min_samples`` samples span half the window.
    A clock that goes back starts it again."""

    def __init__(self) -> None:
        self.rate = math.nan                                    # N/s
        self._samples: deque[tuple[float, float]] = deque()    # (t [s], tension [N])

    def add(self, now: float, value: float, window: float, min_samples: int) -> float:
        """The sample ``value`` [N] at ``now`` [s] (the cell's clock); returns ``rate``."""
        tr = self._samples
        if tr and now < tr[-1][0]:
            tr.clear()                                  # the clock went back: start again
        tr.append((now, value))
        while tr and tr[0][0] < now - window:
            tr.popleft()
        self.rate = math.nan
        if len(tr) < min_samples:
            return self.rate
        t = np.array([p[0] for p in tr])
        f = np.array([p[1] for p in tr])
        if t[-1] - t[0] < 0.5 * window:
            return self.rate
        tc = t - t.mean()
        self.rate = float(np.dot(tc, f - f.mean()) / np.dot(tc, tc))
        return self.rate
