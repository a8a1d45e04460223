"""Parallel evaluation of candidate models against records.

A candidate is a tuple of ``(effect name, values)`` pairs added to each
record's nominal cell.  :class:`Evaluator` runs candidates x records in a
process pool (all cores) and returns, per record, the sums the fit and the
gap figures need (:class:`Stats`).  A model that fails to run (the solver
gives up, e.g. a pinched sheet) scores infinitely bad, never crashes the
diagnosis.
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from typing import Callable, Sequence

import numpy as np

from ..effects import EFFECTS
from ..params import CellParams
from .compare import RecordData, residuals, simulate

Candidate = tuple  # tuple[tuple[str, tuple[float, ...]], ...]


@dataclass(frozen=True)
class Stats:
    """One record against one candidate: sums of squared residuals and gap figures."""

    ok: bool
    sum_p: float = math.inf       # m^2, sum of squared profile residuals
    n_p: int = 0
    sum_f: float = math.inf       # N^2, sum of squared force residuals (x and z)
    n_f: int = 0
    max_p: float = math.inf       # m, largest |profile residual|
    delta_model: float = math.nan  # m
    delta_measured: float = math.nan
    error: str = ""

    def chi2(self, sigma_p: float, sigma_f: float) -> tuple[float, int]:
        """Noise-weighted sum of squares and its count (profile and force)."""
        if not self.ok:
            return math.inf, self.n_p + self.n_f
        total = self.sum_p / sigma_p ** 2 + (self.sum_f / sigma_f ** 2 if self.n_f else 0.0)
        return total, self.n_p + self.n_f


def apply(params: CellParams, candidate: Candidate) -> CellParams:
    for name, values in candidate:
        params = EFFECTS[name].apply(params, values)
    return params


def evaluate_one(data: RecordData, candidate: Candidate) -> Stats:
    try:
        run = simulate(apply(data.record.scenario, candidate), data)
    except (RuntimeError, ValueError, FloatingPointError) as exc:
        return Stats(False, error=f"{type(exc).__name__}: {exc}")
    r = residuals(data, run)
    n_f = 0 if r.force is None else r.force.size
    return Stats(True, float(np.sum(r.profile ** 2)), int(r.profile.size),
                 float(np.sum(r.force ** 2)) if n_f else 0.0, n_f,
                 float(np.max(np.abs(r.profile))), r.delta_model, r.delta_measured)


_DATA: list[RecordData] = []


def _init(data: list[RecordData]) -> None:
    global _DATA
    _DATA = data
    np.seterr(all="ignore")


def _task(args) -> Stats:
    i, candidate = args
    return evaluate_one(_DATA[i], candidate)


class Evaluator:
    """Runs (record, candidate) pairs on ``jobs`` processes; caches results."""

    def __init__(self, data: Sequence[RecordData], jobs: int | None = None,
                 progress: Callable[[int], None] | None = None):
        self.data = list(data)
        self.jobs = max(1, jobs or os.cpu_count() or 1)
        self.progress = progress
        self.cache: dict = {}
        self.runs = 0
        self._pool = None
        if self.jobs > 1:
            self._pool = ProcessPoolExecutor(self.jobs, mp_context=get_context("fork"),
                                             initializer=_init, initargs=(self.data,))
        else:
            _init(self.data)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def stats(self, candidates: Sequence[Candidate], records: Sequence[int]) -> list[list[Stats]]:
        """Stats[candidate][record] for every candidate on the given record indices."""
        keys = [(_key(c), i) for c in candidates for i in records]
        todo = sorted({k for k in keys if k not in self.cache})
        args = [(i, c) for c, i in todo]
        if args:
            results = (self._pool.map(_task, args, chunksize=1) if self._pool is not None
                       else map(_task, args))
            for key, res in zip(todo, results):
                self.cache[key] = res
                self.runs += 1
                if self.progress is not None:
                    self.progress(1)
        return [[self.cache[(_key(c), i)] for i in records] for c in candidates]


def _key(candidate: Candidate) -> Candidate:
    return tuple(sorted((n, tuple(round(float(v), 12) for v in vals)) for n, vals in candidate))
