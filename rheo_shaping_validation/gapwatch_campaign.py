"""Cases of the gap watch's acceptance campaign (benchmarks/gapwatch_*.py).

A case is what ``rheo-shaping record --params FILE --seed S`` makes
(:func:`~rheo_shaping.planning.movement.synthesize_record`, written with
:func:`~rheo_shaping.records.bag.write_record` and read back): the cell with
no effect or one library effect at mid magnitude (the middle of its
``realistic`` range, a random sign for ``tool_offset`` and ``mass_error``),
measured with the default measurement model.  :func:`run_case` feeds it to a
:class:`~.watch.GapWatch` of the nominal cell and says when WARN came, when the
effect became visible (:func:`visible_time`) and, optionally, what the
diagnosis started at WARN says.  Seeds are in the items, so a case reproduces
wherever it runs.
"""
from __future__ import annotations

import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rheo_shaping.diagnosis.baseline import SYMMETRIC, with_sheet
from rheo_shaping.params.gapwatch_params import GapWatchNodeParams
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams
from rheo_shaping.records.bag import read_record, write_record
from rheo_shaping.sheet.effects import EFFECTS, nominal
from rheo_shaping.sheet.simulation import RunResult, run_scenario
from rheo_shaping.gapwatch.feed import diagnose_record, watch_record
from rheo_shaping.gapwatch.floor import ResidualFloor
from rheo_shaping.gapwatch.residuals import signed_distance


@dataclass(frozen=True)
class Case:
    effect: str            # "" for a nominal run
    seed: int
    diagnose: bool = False      # diagnose the run up to the first WARN (what the node does)
    diagnose_end: bool = False  # diagnose the whole run when it warned (the node, at its end)


def mid_magnitude(name: str, rng: np.random.Generator) -> tuple[float, ...]:
    """The middle of effect ``name``'s realistic range (random sign where the range is |value|)."""
    e = EFFECTS[name]
    mid = [0.5 * (lo + hi) for lo, hi in e.realistic]
    if name in ("tool_offset", "mass_error"):
        mid = [v * rng.choice((-1.0, 1.0)) for v in mid]
    return tuple(mid)


def visible_time(truth: RunResult, model: RunResult, profile_noise: float,
                 force_noise: float) -> float | None:
    """First time [s] at which the noise-free truth departs from the model by one noise std:
    a node of the true centreline farther than ``profile_noise`` [m] from the model's, or a
    tool force axis more than ``force_noise`` [N] apart; None if never."""
    t = truth.t
    for k in range(t.size):
        j = int(np.clip(np.searchsorted(model.t, t[k]), 0, model.t.size - 1))
        if np.any(np.abs(truth.tool_force[k] - model.tool_force[j]) > force_noise):
            return float(t[k])
        d = signed_distance(truth.nodes(k)[1:-1], model.nodes(j))
        if np.max(np.abs(d)) > profile_noise:
            return float(t[k])
    return None


def run_case(shared: tuple, case: Case, keep_delta: bool = False) -> dict:
    """One case: (cell, floor, settings, measurement) in ``shared``; the figures as a dict
    (``keep_delta``: with every frame's measured - model Delta [m], for the floor)."""
    cell, floor, settings, ms, commissioning = shared
    rng = np.random.default_rng(case.seed)
    truth = cell
    if commissioning > 0:
        # the model is the cell calibrated to within ``commissioning`` tolerances (its own
        # stream of draws: the effect's sign below is the same as without)
        crng = np.random.default_rng((case.seed, 7))
        truth = with_sheet(cell, {k.name: crng.uniform(-commissioning, commissioning)
                                  for k in SYMMETRIC})
    values: tuple = ()
    if case.effect:
        values = mid_magnitude(case.effect, rng)
        truth = EFFECTS[case.effect].apply(truth, values)
    rec, run = synthesize_record(truth, ms, seed=case.seed, name=f"{case.effect or 'nominal'}"
                                 f"-{case.seed}")
    out: dict = {"effect": case.effect, "seed": case.seed, "values": list(values)}
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp) / rec.name
        write_record(rec, d, truth=truth)                  # as `rheo-shaping record` writes it
        rec = read_record(d)
        snap: list = []
        gw = watch_record(rec, nominal(cell), floor, settings, on_warn=snap.append)
        out.update(first_warn=gw.first_warn, first_error=gw.first_error, level=gw.level,
                   duration=float(rec.duration), cpu_s=gw.cpu_s,
                   refused=sum(gw.refused.values()), max_z=_max_z(gw))
        if keep_delta:
            out["delta_diffs"] = list(gw.delta_diffs)
        if case.effect:
            plan = movement_plan(truth)
            base = run_scenario(nominal(cell), plan)
            out["visible"] = visible_time(run, base, ms.profile_noise, ms.wrench_noise)
        if case.diagnose and snap:
            wd = Path(tmp) / "window"
            write_record(snap[0], wd)
            out["diagnosis"] = diagnose_record(str(wd), str(Path(tmp) / "report"),
                                               settings.diagnosis_baseline)
            out["diagnosis"]["right"] = out["diagnosis"]["verdict"] == case.effect
        if case.diagnose_end and gw.first_warn is not None:
            wd = Path(tmp) / "run"
            write_record(gw.record(), wd)
            out["diagnosis_end"] = diagnose_record(str(wd), str(Path(tmp) / "report_end"),
                                                   settings.diagnosis_baseline)
            out["diagnosis_end"]["right"] = out["diagnosis_end"]["verdict"] == case.effect
    return out


def _max_z(gw) -> list:
    tr = np.array([[np.nan if v is None else v for v in row[1:5]] for row in gw.trace])
    return [float(x) for x in np.nanmax(tr, axis=0)] if tr.size else []


def default_shared(cell: CellParams, floor: ResidualFloor | None = None,
                   settings: GapWatchNodeParams = GapWatchNodeParams(),
                   ms: MeasurementParams = MeasurementParams(),
                   commissioning_error: float = 0.0) -> tuple:
    """What every case shares: the model cell, the floor, the watch's settings, the
    measurement model and the commissioning error (the true cell's sheet knobs off the
    model's by U(-e, e) tolerances each; 0: the model is the cell)."""
    return (nominal(cell), floor if floor is not None else ResidualFloor.load(), settings,
            replace(ms), float(commissioning_error))
