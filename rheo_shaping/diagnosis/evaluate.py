"""Batches of model runs against records: the one seam where simulations are spent.

A :class:`Task` is a record (its flattened :class:`~.compare.RecordData`) and
the full cell to run against it (baseline values and effects already set);
the data travels with the task, so any :class:`concurrent.futures.Executor`
runs it (a local process pool by default; a Dask ``distributed`` client's
``get_executor()`` as well).  :func:`run_batch` returns one
:class:`Outcome` per task, in order: the residual vectors the linearised
fits work on, never the whole run unless asked (``keep_run``).  A model
that fails to run (the solver gives up) gives ``ok = False``, never an
exception.
"""
from __future__ import annotations

import os
from concurrent.futures import Executor
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..sheet.effects import EFFECTS
from ..parallel import run_tasks
from ..params.cell import CellParams
from ..sheet.simulation import RunResult
from .compare import RecordData, residuals, simulate

Candidate = tuple  # tuple[tuple[str, tuple[float, ...]], ...]: (effect name, values) pairs


@dataclass(frozen=True)
class Task:
    """One simulation: the cell ``params`` driven by ``data``'s measured tool pose."""

    data: RecordData
    params: CellParams
    keep_run: bool = False


@dataclass(frozen=True)
class Outcome:
    """One record against one model run (chain uncorrected)."""

    ok: bool
    profile: np.ndarray | None = None      # (P,) m, signed normal distance, measured - model
    normal: np.ndarray | None = None       # (P, 2) unit normal of the model at each foot point
    arc: np.ndarray | None = None          # (P,) m, arc length of the foot point
    force: np.ndarray | None = None        # (W, 2) N, measured - model tool force
    model_force: np.ndarray | None = None  # (W, 2) N, model tool force at the wrench stamps
    model_dforce: np.ndarray | None = None  # (W, 2) N/s, its time derivative
    delta_model: float = float("nan")      # m, Delta of the model at the last frame
    delta_measured: float = float("nan")   # m
    F_max: float = float("nan")            # N
    run: RunResult | None = None
    error: str = ""

    @property
    def kept_run(self) -> RunResult:
        """The model run of a task with ``keep_run`` that ran."""
        if self.run is None:
            raise ValueError(f"outcome has no run ({self.error or 'not kept'})")
        return self.run

    def array(self, name: str) -> np.ndarray:
        """Residual array ``name`` (``profile``, ``normal``, ``arc``; ``force``,
        ``model_force``, ``model_dforce`` when the record has forces) of an outcome that ran."""
        value = getattr(self, name)
        if value is None:
            raise ValueError(f"outcome has no {name} ({self.error or 'its record has none'})")
        return value


def all_ok(outs: Sequence[Outcome]) -> bool:
    """Every outcome ran."""
    return all(o.ok for o in outs)


def apply(params: CellParams, candidate: Candidate) -> CellParams:
    """``params`` with the effects of ``candidate`` switched on."""
    for name, values in candidate:
        params = EFFECTS[name].apply(params, values)
    return params


def run_task(task: Task) -> Outcome:
    """Run one task (in a worker process or here)."""
    np.seterr(all="ignore")
    data = task.data
    try:
        run = simulate(task.params, data)
    except (RuntimeError, ValueError, FloatingPointError) as exc:
        return Outcome(False, error=f"{type(exc).__name__}: {exc}")
    r = residuals(data, run)
    mf = md = None
    if r.force is not None:
        t = data.record.wrench_t
        # residuals() gives a force exactly when the record has one, stamps with it
        assert t is not None and data.record.wrench_xz is not None
        mf = data.record.wrench_xz - r.force
        md = np.gradient(mf, t, axis=0) if t.size > 1 else np.zeros_like(mf)
    if not (np.all(np.isfinite(r.profile)) and (r.force is None or np.all(np.isfinite(r.force)))):
        return Outcome(False, error="non-finite residuals")
    return Outcome(True, r.profile, r.normal, r.arc, r.force, mf, md, r.delta_model,
                   r.delta_measured, float(run.F_max), run if task.keep_run else None)


def default_executor(jobs: int | None = None) -> Executor:
    """A local process pool on ``jobs`` processes (default: all cores; rheo_shaping.parallel)."""
    from ..parallel import local_pool
    return local_pool(max(1, jobs or os.cpu_count() or 1))


#: The diagnosis's stages, in order (a progress display shows "stage k of n"); a stage
#: that has nothing to run (the replay misfit of a Maxwell cell, the effects when no gap
#: is left) is passed over.
STAGES = ("laid sheets' lengths", "nominal models", "baseline Jacobian", "baseline fit",
          "laid lengths and baseline again", "the laid start, to compare",
          "replay misfit (Kelvin cell)", "effect probes", "candidate checks", "verdict runs")


class Runner:
    """Counts and runs batches on an executor (owned when made here, else the caller's)."""

    def __init__(self, executor: Executor | None = None, jobs: int | None = None,
                 progress: Callable[[int], None] | None = None):
        self._own = executor is None and (jobs or os.cpu_count() or 1) > 1
        self.executor = default_executor(jobs) if self._own else executor
        self.progress = progress
        self.runs = 0
        self._k = 0                 # the stage under way (1-based; 0 before the first)
        self._blas: AbstractContextManager | None = None   # held between enter and exit

    def stage(self, name: str, total: int | None = None) -> None:
        """Stage ``name`` of :data:`STAGES` begins, with ``total`` simulations when known
        up front (None: its batches add theirs as they start); told to a progress display
        that has a ``stage(k, n, name, total)`` method (k counts from 1).  A stage before the
        one under way is a part of it (the second pass of a laid sheet's stages): not told."""
        k = STAGES.index(name) + 1
        if k <= self._k:
            return
        self._k = k
        stage = getattr(self.progress, "stage", None)
        if stage is not None:
            stage(k, len(STAGES), name, total)

    def map(self, fn: Callable, items: Sequence) -> list:
        """``fn(None, item)`` for every item, in order, on this runner's executor, counted
        as simulations (for a stage whose runs are not :class:`Task` s)."""
        expect = getattr(self.progress, "expect", None)
        if expect is not None:             # a progress display learns each batch's size first
            expect(len(items))
        return run_tasks(self.executor, fn, None, list(items), self._count)

    def __call__(self, tasks: Sequence[Task]) -> list[Outcome]:
        return self.map(_run_one, tasks)

    def _count(self, n: int) -> None:
        self.runs += n
        if self.progress is not None:
            self.progress(n)

    def close(self) -> None:
        if self._own and self.executor is not None:
            self.executor.shutdown()

    def __enter__(self):
        # the stages' own linear algebra on one BLAS thread while the workers simulate
        # (:func:`.blas.blas_single_thread`)
        from .blas import blas_single_thread
        self._blas = blas_single_thread()
        self._blas.__enter__()
        return self

    def __exit__(self, *exc):
        try:
            self.close()
        finally:
            blas, self._blas = self._blas, None
            if blas is not None:
                blas.__exit__(None, None, None)


def run_batch(tasks: Sequence[Task], executor: Executor | None = None,
              progress: Callable[[int], None] | None = None) -> list[Outcome]:
    """Every task's outcome, in order; on ``executor`` (None: here, one after another),
    through the package's one seam (:func:`rheo_shaping.parallel.run_tasks`)."""
    return run_tasks(executor, _run_one, None, list(tasks), progress)


def _run_one(_shared, task: Task) -> Outcome:
    return run_task(task)
