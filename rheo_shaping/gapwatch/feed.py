"""Feeding the gap watch, and the diagnosis it starts.

:func:`watch_record` replays a :class:`~rheo_shaping.records.record.Record` into a
:class:`~.watch.GapWatch` in stamp order, as a live cell would deliver it (the
benchmarks and tests).  :func:`diagnose_record` is what the watch's worker
process runs on a sustained WARN: it reads a record directory, diagnoses it
(:func:`rheo_shaping.diagnosis.engine.diagnose`, serially in that process),
writes the report and returns a :class:`Verdict` as a plain dict.
:class:`DiagnosisJobs` hands it to an executor of :mod:`rheo_shaping.parallel`
(never the node's own thread) and keeps one job at a time.
"""
from __future__ import annotations

import time
from concurrent.futures import Executor, Future
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..params.gapwatch_params import GapWatchNodeParams
from ..params.cell import CellParams
from ..records.record import Record
from .floor import ResidualFloor
from .watch import GapWatch

#: A baseline knob is reported with a verdict when it moved this share of its tolerance.
BASELINE_SHOWN = 0.5
#: Process time [s] between the watch's updates when a record is replayed into it.
FEED_STEP_S = 0.1


def watch_record(record: Record, model: CellParams | None = None,
                 floor: ResidualFloor | None = None,
                 settings: GapWatchNodeParams = GapWatchNodeParams(),
                 step: float = FEED_STEP_S,
                 on_warn: Callable[[Record], None] | None = None) -> GapWatch:
    """A :class:`GapWatch` of ``model`` (default: the record's scenario) fed ``record`` in stamp
    order, updated every ``step`` [s] of process time and once more at the end; ``on_warn``
    gets the watch's record of the run so far at the first WARN (what the node diagnoses)."""
    gw = GapWatch(model if model is not None else record.scenario,
                  floor if floor is not None else ResidualFloor.load(), settings)
    gw.start(0.0)
    pose = (record.pose_t, record.pose_xz)
    wt: np.ndarray = np.zeros(0)
    wxz: np.ndarray = np.zeros((0, 2))
    if record.wrench_t is not None and record.wrench_xz is not None:
        wt, wxz = record.wrench_t, record.wrench_xz
    ip = iw = ifr = 0
    t = 0.0
    end = record.duration
    while True:
        while ip < pose[0].size and pose[0][ip] <= t + 1e-12:
            gw.pose(float(pose[0][ip]), *map(float, pose[1][ip]))
            ip += 1
        while ifr < record.profile_t.size and record.profile_t[ifr] <= t + 1e-12:
            gw.profile(float(record.profile_t[ifr]), record.profiles[ifr])
            ifr += 1
        while iw < wt.size and wt[iw] <= t + 1e-12:
            gw.wrench(float(wt[iw]), *map(float, wxz[iw]))
            iw += 1
        if t > end:
            break
        warned = gw.first_warn is not None
        gw.update()
        if on_warn is not None and not warned and gw.first_warn is not None:
            on_warn(gw.record())
        t += step
    gw.update(final=True)
    return gw


@dataclass(frozen=True)
class Verdict:
    """A diagnosis the watch started: what it says and where its report is."""

    verdict: str                          # an effect's name, "none" or "unexplained"
    parameters: dict = field(default_factory=dict)   # the verdict's fitted values
    p: float | None = None
    report: str = ""                      # path of report.md
    record: str = ""                      # the record it read
    wall_time_s: float = 0.0
    error: str = ""                       # why it failed (then verdict is "failed")
    baseline: dict = field(default_factory=dict)   # the calibrated baseline's knobs moved by
    # at least BASELINE_SHOWN of their tolerance: name -> (value, written, unit, u)
    p_gap: float | None = None            # the gap test's p-value


def diagnose_record(record_dir: str, out_dir: str, baseline: str = "held") -> dict:
    """Diagnose the record in ``record_dir`` (all library effects, serially; the sheet knobs
    ``held`` as the model cell writes them, or ``calibrated``: ``diagnose --baseline``), write
    the report into ``out_dir``; a :class:`Verdict` as a dict (a worker process's task)."""
    t0 = time.monotonic()
    try:
        from ..diagnosis.engine import diagnose
        from ..diagnosis.report import write
        from ..records.bag import read_record
        rec = read_record(record_dir)
        # the model's own records: its sheet settled, judged against its numerics
        diag = diagnose([rec], jobs=1, baseline=baseline, initial_state="settled",
                        floor="numerics")
        paths = write(diag, Path(out_dir))
        fit = diag.verdict_fit
        params = {} if fit is None else {k: [float(x) for x in v] for k, v in fit.values.items()}
        report = next((str(p) for p in paths if str(p).endswith(".md")), str(out_dir))
        moved = {k: [b.get("value"), b.get("written"), b.get("unit", ""), b.get("u")]
                 for k, b in diag.baseline.items()
                 if isinstance(b, dict) and abs(b.get("u") or 0.0) >= BASELINE_SHOWN}
        v = Verdict(diag.verdict_name, params, None if fit is None else float(fit.p), report,
                    str(record_dir), time.monotonic() - t0, baseline=moved,
                    p_gap=float(diag.p_gap))
    except Exception as exc:  # noqa: BLE001 - a failed diagnosis is reported, not raised
        v = Verdict("failed", record=str(record_dir), wall_time_s=time.monotonic() - t0,
                    error=f"{type(exc).__name__}: {exc}")
    return asdict(v)


class DiagnosisJobs:
    """At most one diagnosis at a time on ``executor`` (a worker process pool)."""

    def __init__(self, executor: Executor, baseline: str = "held"):
        self.executor = executor
        self.baseline = baseline
        self.future: Future | None = None
        self.last: dict | None = None

    @property
    def busy(self) -> bool:
        return self.future is not None and not self.future.done()

    def submit(self, record_dir: str, out_dir: str) -> Future | None:
        """Start a diagnosis of ``record_dir``; None while one runs."""
        if self.busy:
            return None
        self.future = self.executor.submit(diagnose_record, record_dir, out_dir, self.baseline)
        return self.future
