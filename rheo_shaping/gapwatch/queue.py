"""The samples that wait for the gap watch's model: filled by the node's callbacks (the
executor's thread), drained by its worker thread, read by its reports; every operation
under one lock (a report read the queue's length and then its first sample while the
worker emptied it: an ``IndexError`` that took the node down).  Times are
``time.monotonic()`` seconds.  No ROS imports here.
"""
from __future__ import annotations

import threading
from collections import deque
from typing import Any


class SampleQueue:
    """A bounded first-in first-out queue of ``(kind, stamp, value)`` samples, each kept with
    its arrival time [s]; at ``limit`` the oldest sample goes first."""

    def __init__(self, limit: int):
        if limit < 1:
            raise ValueError(f"queue limit = {limit!r} is invalid: expected an integer >= 1")
        self.limit = int(limit)
        self._items: deque[tuple[Any, ...]] = deque()
        self._lock = threading.Lock()

    def put(self, item: tuple[Any, ...], now: float) -> bool:
        """Queue ``item`` received at ``now`` [s]; True when the oldest sample was dropped
        to make room."""
        with self._lock:
            dropped = len(self._items) >= self.limit
            if dropped:
                self._items.popleft()
            self._items.append(item + (now,))
            return dropped

    def pop(self) -> tuple[Any, ...] | None:
        """The oldest sample with its arrival time last, or None when empty."""
        with self._lock:
            return self._items.popleft() if self._items else None

    def waiting(self, now: float) -> tuple[int, float]:
        """(samples waiting, age [s] of the oldest of them; 0 when none)."""
        with self._lock:
            n = len(self._items)
            return n, (now - self._items[0][-1]) if n else 0.0

    def clear(self) -> int:
        """Drop every waiting sample; how many there were."""
        with self._lock:
            n = len(self._items)
            self._items.clear()
            return n

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)
