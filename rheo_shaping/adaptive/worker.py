"""The closed loop's refreshes in a process of their own: an estimate and a re-plan take
tenths of a second of CPU in compiled code that holds Python's global interpreter lock, and a
node must not stand still meanwhile (the one-process cell's monitor shares the planner's
interpreter).  No ROS here.

:class:`ShaperProcess` keeps a bookkeeping :class:`~.online.OnlineShaper` in the caller
(which samples it wants, when a refresh is due, the schedule the stream follows) and the
working one in one worker process (``spawn``: no thread of the caller is copied); each
:meth:`~ShaperProcess.submit` sends the new samples and returns a future of the
:class:`~.online.OnlineStep`; :meth:`~ShaperProcess.accept` tells both that the stream
switched to a step's plan.
"""
from __future__ import annotations

import multiprocessing
import time
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Sequence

from ..params.cell import CellParams
from .observe import Sample
from .online import OnlineConfig, OnlineShaper, OnlineStep, Reason

_SHAPER: OnlineShaper | None = None       # the worker process's own


def _start(cell: CellParams, config: OnlineConfig) -> float:
    """(in the worker) A new run's shaper; returns its CPU time [s]."""
    global _SHAPER
    cpu = time.process_time()
    _SHAPER = OnlineShaper(cell, config)
    return time.process_time() - cpu


def _refresh(samples: Sequence[Sample], t: float, reason: Reason,
             executed_xz: tuple[float, float] | None, streamed: float, lead: float,
             accepted: int | None) -> tuple[int, OnlineStep, float]:
    """(in the worker) Take the accepted step, the samples, refresh; (the step's index, the
    step, the worker's CPU time [s] for it)."""
    cpu = time.process_time()
    shaper = _SHAPER
    if shaper is None:
        raise RuntimeError("the closed loop's worker has no run: start() first")
    if accepted is not None:
        shaper.accept(shaper.steps[accepted])
    for s in samples:
        shaper.add(s)
    step = shaper.refresh(t, reason, executed_xz=executed_xz, streamed=streamed, lead=lead)
    return len(shaper.steps) - 1, step, time.process_time() - cpu


class ShaperProcess:
    """The closed loop of one run after another, its refreshes in one worker process."""

    def __init__(self, cell: CellParams | None = None,
                 config: OnlineConfig = OnlineConfig()) -> None:
        """The worker process starts at once and, given ``cell``, builds a shaper of it
        (its imports and compiled code warm before a run needs them: :attr:`warm`)."""
        self._pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
        self.shaper: OnlineShaper | None = None     # the bookkeeping copy of this run
        self._accepted: int | None = None
        self.cpu_s = 0.0                             # the worker's CPU time of this run [s]
        self._started: Future | None = None
        if cell is not None:
            self._started = self._pool.submit(_start, cell, config)

    @property
    def warm(self) -> bool:
        """The worker has built its first shaper (a refresh then takes its own time only)."""
        return self._started is None or self._started.done()

    def start(self, cell: CellParams, config: OnlineConfig) -> OnlineShaper:
        """A new run of ``cell`` (the worker builds its shaper meanwhile); the bookkeeping
        shaper, whose ``plan`` the stream starts with."""
        self.shaper = OnlineShaper(cell, config)
        self._accepted, self.cpu_s = None, 0.0
        self._pool.submit(_start, cell, config)      # (before any refresh: one worker)
        return self.shaper

    def submit(self, samples: Sequence[Sample], t: float, reason: Reason,
               executed_xz: tuple[float, float] | None, streamed: float,
               lead: float) -> Future:
        """Begin a refresh at process time ``t`` [s] with the ``samples`` since the last
        one; a future of (index, :class:`OnlineStep`, worker CPU [s])."""
        if self.shaper is None:
            raise RuntimeError("ShaperProcess.submit() before start()")
        self.shaper.begin(t, drop_samples=True)
        accepted, self._accepted = self._accepted, None
        return self._pool.submit(_refresh, list(samples), t, reason, executed_xz, streamed,
                                 lead, accepted)

    def accept(self, index: int, step: OnlineStep) -> None:
        """The stream follows step ``index``'s plan from its join on."""
        if self.shaper is not None:
            self.shaper.accept(step)
        self._accepted = index

    def close(self) -> None:
        """End the worker process (a refresh under way is abandoned)."""
        self._pool.shutdown(wait=False, cancel_futures=True)
