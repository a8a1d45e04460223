"""Each laid record's rest length, from its own first seconds (issue 26, point 2).

The first frame gives a laid sheet's length to within its smoothing and the
camera (0.4-1.3 mm on the dynamic world, against 0.2 mm of profile noise), and
no two layings need be of one length: a sheet laid over a tool that stands in
its way is laid longer (2-2.5 mm on the dynamic world's movement 2 when the
sheet's sag would cross the tool). One common length for every record, or
each record's first-frame reading, leaves what a baseline knob shared by all
records cannot take: on 5 of 20 effect-free calibration layings it left J - 1
of 1-12 where the others left 0.05-0.13 (the dynamic world's first floor calibration).

So each laid record's model gets an offset of its rest length, fitted on that
record alone to the frames of its first ``WINDOW`` seconds after the fall
(``RELEASE_TIME`` after the first frame): the sheet's own settling, before the
process has moved it much. A one-dimensional fit: the mean squared distance of
the window's measured points from the model's centreline, on a grid of
``GRID`` mm then two finer grids, and a parabola through the best three points.
It runs twice in a diagnosis: with the written cell, and again with the
calibrated baseline's, whose bonds and sag move the same length
(:func:`rheo_shaping.diagnosis.engine.diagnose`).

What it can take from an effect: one number per record, fitted on the first
seconds only. An effect that acts in the settle (friction on the mould, for
one) and changes the sag like a longer sheet is partly absorbed there; the
verdict's remainder is then smaller than the effect's share of the records.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from ..params.cell import CellParams
from ..sheet.simulation import run_scenario
from .compare import RecordData, polylines_at
from .initial_state import RELEASE_TIME, distance_to

#: Length [s] of the window after the fall whose frames fit a record's rest length.
WINDOW = 3.0
#: The coarse grid of rest-length offsets [m] (centred on the record's reading).
GRID = tuple(np.linspace(-3e-3, 3e-3, 7))
#: Frames needed in the window to fit an offset (fewer: the offset stays 0).
MIN_FRAMES = 2


def window_frames(d: RecordData) -> np.ndarray:
    """Indices of ``d``'s profile frames in its fit window (after the fall, ``WINDOW`` s)."""
    st = d.initial
    if st is None or st.mode != "laid":
        return np.zeros(0, dtype=int)
    t = np.asarray(d.record.profile_t, float)
    start = st.t0 + RELEASE_TIME
    sel = np.nonzero((t >= start) & (t <= start + WINDOW))[0]
    return np.array([i for i in sel if np.asarray(d.record.profiles[i]).size >= 10], dtype=int)


def window_misfit(params: CellParams, d: RecordData, offset: float) -> float:
    """Mean squared distance [m^2] of the window's measured points from the model's
    centreline, the model started from ``d``'s laid sheet with its rest length moved by
    ``offset`` [m]; inf when the model does not run."""
    st = d.initial
    assert st is not None
    laid = replace(st, offset=st.offset + offset).laid(params)
    frames = window_frames(d)
    t = np.asarray(d.record.profile_t, float)[frames]
    try:
        run = run_scenario(params, d.path, t_end=float(t[-1]) + 1e-6, laid=laid)
    except (RuntimeError, ValueError, FloatingPointError):
        return math.inf
    lines = polylines_at(run, t)
    r = [distance_to(np.asarray(d.record.profiles[f], float).reshape(-1, 2), lines[k])
         for k, f in enumerate(frames)]
    v = float(np.mean(np.concatenate(r) ** 2))
    return v if math.isfinite(v) else math.inf


def _misfit_task(shared, task) -> float:
    params, d, offset = task
    return window_misfit(params, d, offset)


def _vertex(x: np.ndarray, c: np.ndarray, k: int) -> float:
    """The parabola's minimum through points k-1, k, k+1 (within them), else x[k]."""
    a, b, _ = np.polyfit(x[k - 1:k + 2], c[k - 1:k + 2], 2)
    return float(np.clip(-b / (2 * a), x[k - 1], x[k + 1])) if a > 0 else float(x[k])


def length_fitted(d: RecordData) -> bool:
    """Whether a record's rest-length offset is fitted: it is laid, with ``MIN_FRAMES``
    frames or more in its window."""
    return len(window_frames(d)) >= MIN_FRAMES


def fit_offsets(data: Sequence[RecordData], params: Sequence[CellParams],
                batch: Callable[[Callable, list], list] | None = None) -> list[float]:
    """Each laid record's rest-length offset [m] (0 for a settled one or one without
    ``MIN_FRAMES`` frames in its window), fitted for cell ``params[i]``; every record's
    grid runs in one ``batch(fn, items)`` (a :meth:`~.evaluate.Runner.map`; None: here)."""
    todo = [i for i, d in enumerate(data) if length_fitted(d)]
    out = [0.0] * len(data)
    if not todo:
        return out
    grids = {i: np.array(GRID) for i in todo}
    best = {i: 0.0 for i in todo}
    for _level in range(3):                     # the coarse grid, then two finer ones
        tasks = [(params[i], data[i], float(x)) for i in todo for x in grids[i]]
        costs = (batch(_misfit_task, tasks) if batch is not None
                 else [_misfit_task(None, t) for t in tasks])
        k0 = 0
        for i in todo:
            x = grids[i]
            c = np.array(costs[k0:k0 + len(x)])
            k0 += len(x)
            if not np.isfinite(c).any():
                best[i] = 0.0
                continue
            k = int(np.clip(np.argmin(c), 1, len(x) - 2))
            best[i] = _vertex(x, c, k) if np.isfinite(c[k - 1:k + 2]).all() else float(x[k])
            half = 0.25 * 0.5 * (x[-1] - x[0])          # the next grid: a quarter as wide
            grids[i] = best[i] + np.linspace(-half, half, 5)
    for i in todo:
        out[i] = best[i]
    return out


def laid_lengths(data: Sequence[RecordData], params: Sequence[CellParams],
                 run) -> list[RecordData]:
    """Stage 1 of a diagnosis (:data:`~.evaluate.STAGES`): ``data`` with every laid record's
    rest-length offset fitted for cell ``params[i]`` on ``run`` (an
    :class:`~.evaluate.Runner`; its executor and progress)."""
    if not any(length_fitted(d) for d in data):
        return list(data)
    run.stage("laid sheets' lengths")
    return with_offsets(data, fit_offsets(data, params, run.map))


def with_offsets(data: Sequence[RecordData], offsets: Sequence[float]) -> list[RecordData]:
    """``data`` whose laid records' rest lengths are moved by ``offsets`` [m] (added to the
    offset each already has)."""
    return [d if d.initial is None or o == 0.0 else
            replace(d, initial=replace(d.initial, offset=d.initial.offset + o))
            for d, o in zip(data, offsets)]


__all__ = ["WINDOW", "GRID", "fit_offsets", "laid_lengths", "length_fitted", "with_offsets",
           "window_misfit"]
