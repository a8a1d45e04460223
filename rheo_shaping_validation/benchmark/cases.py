"""A benchmark case: records of a TRUE cell that differs from the one the diagnosis is told
about (the record's ``scenario``) as a real cell would.

* the world (:mod:`.world`): the sheet model on finer numerics, or the dynamic world, a
  simulator of another form;
* the written scenario: every two-sided baseline knob
  (:data:`~rheo_shaping.diagnosis.baseline.SYMMETRIC`) is written off its true value by a
  draw within +-0.8 of its tolerance (the contact's stiffness is the model's, rigid);
* the measurement chain: the vision offset and the load cell's bias, gain and lag are off by
  draws within +-0.8 of their tolerances.

On top, by kind (:data:`KINDS_PATTERN`, each case its own seed ``seed * 1000 + index``):
``single`` (one library effect at a magnitude drawn from ``Effect.realistic``), ``none``,
``sensor`` (one chain error beyond its tolerance, :data:`SENSOR_ERRORS`; the right answer is
no sheet effect and the measurement side flagged) and ``out_of_library`` (one effect removed
from the diagnosis's library; on a world with effects of its own, one of those with the whole
library fitted).  Three records per case on movements drawn from 1-4; two fitted, one held
out.  A draw whose true run tears the sheet or fails is redrawn.
"""
from __future__ import annotations

import random
from dataclasses import replace

import numpy as np

from rheo_shaping.diagnosis.baseline import CHAIN, SYMMETRIC, with_sheet
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.records.measurement import MeasurementParams
from rheo_shaping.sheet.effects import EFFECT_NAMES, EFFECTS
from rheo_shaping_validation.worlds.params import WORLD_EFFECTS, WORLD_EFFECT_NAMES, WorldEffects
from .world import WORLDS, check_world

KINDS_PATTERN = ("single", "none", "single", "out_of_library", "single", "none", "single",
                 "sensor", "single", "out_of_library")
#: Chain errors beyond tolerance for ``sensor`` cases: (knob, |value| range in its unit).
SENSOR_ERRORS = (("vision.dx", (1.5e-3, 3e-3)), ("vision.dz", (1.5e-3, 3e-3)),
                 ("load_cell.gain", (0.10, 0.25)), ("load_cell.lag", (0.2, 0.5)),
                 ("load_cell.bias_x", (0.05, 0.1)), ("load_cell.bias_z", (0.05, 0.1)))
#: Draws per case before it is given up (:class:`NoCase`).
DRAWS = 20


def base_cell(n_masses: int = 31, process_time: float = 70.0) -> CellParams:
    """The cell the diagnosis is told about (before the written values are perturbed)."""
    p = CellParams()
    return replace(p, sheet=replace(p.sheet, n_masses=n_masses),
                   movement=replace(p.movement, process_time=process_time))


def draw_value(name: str, rng: random.Random) -> tuple[float, ...]:
    """A realistic magnitude of effect ``name``."""
    vals = []
    for lo, hi in EFFECTS[name].realistic:
        v = rng.uniform(lo, hi)
        if name in ("tool_offset", "mass_error"):
            v *= rng.choice((-1.0, 1.0))
        vals.append(v)
    return tuple(vals)


class NoCase(RuntimeError):
    """Every draw of a case was refused: a record tore the sheet (F_max >= F_break), failed to
    run, or the cell left its parameters' bounds.  The benchmark counts such a case apart."""


def make_case(index: int, kind: str, seed: int, base: CellParams,
              measurement: MeasurementParams = MeasurementParams(),
              world: str = "finer-chain", n_records: int = 3,
              variations: tuple = (), always_on: tuple = (), strata: int = 0) -> dict:
    """Draw a case (its own seed) and record its ``n_records`` runs (movements drawn from 1-4
    without repeats) in ``world`` (:data:`~.world.WORLDS`); on the dynamic world, in a form
    with ``variations`` drawn (none drawn: the plain dynamic world; ``strata`` > 0: stratified
    over that many cases, a floor's calibration)."""
    case_world = WORLDS[check_world(world)].for_case(seed, index, variations, always_on,
                                                     measurement, strata)
    rng = random.Random(seed * 1000 + index)
    why = {"tore": 0, "failed": 0, "outside": 0}
    for _attempt in range(DRAWS):
        truth_effects: tuple = ()
        extra = WorldEffects()
        if kind == "out_of_library" and case_world.own_effects:   # one of the world's own
            name = WORLD_EFFECT_NAMES[rng.randrange(len(WORLD_EFFECT_NAMES))]
            value = WORLD_EFFECTS[name].draw(rng)
            extra = extra.with_value(name, value)
            truth_effects = ((name, (value,)),)
        elif kind in ("single", "out_of_library"):
            name = EFFECT_NAMES[(index // 2 + (kind == "out_of_library") * 3 + rng.randrange(2))
                                % len(EFFECT_NAMES)] if kind == "out_of_library" else \
                EFFECT_NAMES[(index // 2 + index) % len(EFFECT_NAMES)]
            truth_effects = ((name, draw_value(name, rng)),)
        perturb = {k.name: rng.uniform(-0.8, 0.8) for k in SYMMETRIC}
        chain = {k.name: rng.uniform(-0.8, 0.8) * k.tolerance for k in CHAIN}
        sensor = None
        if kind == "sensor":
            knob, (lo, hi) = SENSOR_ERRORS[index % len(SENSOR_ERRORS)]
            chain[knob] = rng.uniform(lo, hi) * (rng.choice((-1.0, 1.0)) if knob != "load_cell.lag"
                                                 else 1.0)
            sensor = knob
        written = base
        try:
            truth = with_sheet(base, {k: -v for k, v in perturb.items()})
        except ValueError:
            why["outside"] += 1
            continue
        for n, v in truth_effects:
            if n in EFFECTS:
                truth = EFFECTS[n].apply(truth, v)
        drawn = case_world.drawn(rng, extra)            # the dynamic world draws its laying
        truth = drawn.true_cell(truth)
        movements = rng.sample((1, 2, 3, 4), n_records)
        records, ok = [], True
        nrng = np.random.default_rng(rng.randrange(2 ** 31))
        for mv in movements:
            t_cell = replace(truth, movement=replace(truth.movement, number=mv))
            w_cell = replace(written, movement=replace(written.movement, number=mv))
            try:
                path = movement_plan(t_cell)
                run = drawn.run(t_cell, path)
            except (RuntimeError, ValueError):
                why["failed"] += 1
                ok = False
                break
            if run.F_max >= t_cell.material.F_break:
                why["tore"] += 1
                ok = False
                break
            rec = drawn.measure(run, path, t_cell, nrng, chain, f"case{index}-m{mv}")
            records.append(replace(rec, scenario=w_cell))
        if ok:
            true_u = {k: -v for k, v in perturb.items()}
            true_u.update({k.name: chain[k.name] / k.tolerance for k in CHAIN})
            return {"index": index, "kind": kind, "truth": truth_effects, "movements": movements,
                    "records": records, "true_u": true_u, "sensor": sensor, "world": world,
                    **drawn.describe()}
    raise NoCase(f"case {index} of seed {seed}: no valid {kind} case in {DRAWS} draws "
                 f"({why['tore']} tore the sheet in a record, {why['failed']} failed to run, "
                 f"{why['outside']} put the cell outside its parameters' bounds)")
