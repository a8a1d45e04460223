"""The worlds that make a benchmark case's records: one :class:`World` protocol, which the
sheet model on finer numerics (:class:`FinerChain`) and the dynamic world
(:class:`DynamicWorld`, :mod:`rheo_shaping_validation.worlds`) both implement, so a case
names its world and asks it to run and measure (:data:`WORLDS`)."""
from __future__ import annotations

import random
from dataclasses import dataclass, replace
from typing import ClassVar, Iterable, Protocol

import numpy as np

from rheo_shaping.diagnosis.check import REFINEMENT
from rheo_shaping.diagnosis.options import DEFAULTS, FloorKind, InitialMode, Options
from rheo_shaping.params.cell import CellParams
from rheo_shaping.records.measurement import MeasurementParams, measure
from rheo_shaping.records.record import Record
from rheo_shaping.sheet.simulation import RunResult, run_scenario
from rheo_shaping_validation.worlds.dynamic import WorldRun, run_world
from rheo_shaping_validation.worlds.forms import FormParams, case_form
from rheo_shaping_validation.worlds.params import (LayParams, WorldEffects, WorldNumerics,
                                                   draw_lay)
from rheo_shaping_validation.worlds.sensors import SensorParams, measure_world

#: How the true cell's numerics differ from the scenario's (factor on the scenario's values).
TRUE_NUMERICS = {**REFINEMENT, "contact_stiffness": 1.0 / 3.0}


class World(Protocol):
    """A simulator standing in for the real cell: the truth a case's records come from."""

    name: ClassVar[str]
    options: ClassVar[Options]      # the diagnosis's switches its records are judged with
    own_effects: ClassVar[bool]     # out-of-library cases carry one of its own effects

    @classmethod
    def for_case(cls, seed: int, index: int, variations: Iterable = (),
                 always_on: Iterable = (),
                 measurement: MeasurementParams = MeasurementParams(),
                 strata: int = 0) -> World:
        """The world of case ``index`` of ``seed`` (its own random stream; ``strata`` > 0:
        its form one of that many stratified calibration cases, where it has a form)."""

    def drawn(self, rng: random.Random, extra: WorldEffects) -> World:
        """This world for one draw of a case, with what it draws from ``rng``."""

    def true_cell(self, cell: CellParams) -> CellParams:
        """The true cell as this world runs it."""

    def run(self, cell: CellParams, path) -> RunResult | WorldRun:
        """The true run of ``cell`` on tool path ``path``."""

    def measure(self, run, path, cell: CellParams, rng: np.random.Generator, chain: dict,
                name: str) -> Record:
        """The record of ``run`` through the chain errors ``chain`` (knob -> value)."""

    @classmethod
    def true_n_masses(cls, n_masses: int) -> int:
        """The true chain's masses for a diagnosis chain of ``n_masses``."""

    def describe(self) -> dict:
        """The world's drawn parts, for the case's row (``lay``, ``form``)."""


def true_numerics(p: CellParams) -> CellParams:
    """``p`` on the true cell's discretisation: 2 N + 1 masses, half steps, softer contact."""
    s = p.solver
    solver = replace(s, **{k: getattr(s, k) * f for k, f in TRUE_NUMERICS.items()})
    return replace(p, sheet=replace(p.sheet, n_masses=2 * p.sheet.n_masses + 1), solver=solver)


def measure_chain(run, path, truth: CellParams, ms: MeasurementParams, rng: np.random.Generator,
                  chain: dict, name: str) -> Record:
    """The sensors' view of ``run`` with chain errors ``chain`` (knob -> value in its unit)."""
    rec = measure(run, path, truth, ms, rng, name)
    off = np.array([chain.get("vision.dx", 0.0), chain.get("vision.dz", 0.0)])
    profiles = tuple(f + off for f in rec.profiles)
    wrench = rec.wrench_xz
    if rec.has_wrench:
        t = rec.wrench_t - chain.get("load_cell.lag", 0.0)
        f = np.c_[np.interp(t, run.t, run.tool_force[:, 0]),
                  np.interp(t, run.t, run.tool_force[:, 1])]
        wrench = ((1.0 + chain.get("load_cell.gain", 0.0)) * f
                  + np.array([chain.get("load_cell.bias_x", 0.0),
                              chain.get("load_cell.bias_z", 0.0)])
                  + rng.normal(0.0, ms.wrench_noise, f.shape))
    return replace(rec, profiles=profiles, wrench_xz=wrench)


@dataclass(frozen=True)
class FinerChain:
    """The sheet model itself on finer numerics (:data:`TRUE_NUMERICS`: 2 N + 1 masses, half
    steps, a contact three times softer), measured by the model's sensors: its null measures
    numerics only."""

    measurement: MeasurementParams = MeasurementParams()
    name: ClassVar[str] = "finer-chain"
    options: ClassVar[Options] = Options(initial_state=InitialMode.SETTLED,
                                         floor=FloorKind.NUMERICS)
    own_effects: ClassVar[bool] = False

    @classmethod
    def for_case(cls, seed: int, index: int, variations: Iterable = (),
                 always_on: Iterable = (),
                 measurement: MeasurementParams = MeasurementParams(),
                 strata: int = 0) -> FinerChain:
        return cls(measurement)

    def drawn(self, rng: random.Random, extra: WorldEffects) -> FinerChain:
        return self

    def true_cell(self, cell: CellParams) -> CellParams:
        return true_numerics(cell)

    def run(self, cell: CellParams, path) -> RunResult:
        return run_scenario(cell, path)

    def measure(self, run, path, cell: CellParams, rng: np.random.Generator, chain: dict,
                name: str) -> Record:
        return measure_chain(run, path, cell, self.measurement, rng, chain, name)

    @classmethod
    def true_n_masses(cls, n_masses: int) -> int:
        return 2 * n_masses + 1

    def describe(self) -> dict:
        return {"lay": None, "form": FormParams().as_dict()}


@dataclass(frozen=True)
class DynamicWorld:
    """The dynamic world (:mod:`rheo_shaping_validation.worlds`): inertia, soft contact with
    friction, the sheet laid in a drawn shape and released at t = 0, its own effects and
    sensors (camera 0.2 mm, load cell 5 mN, pose 0.05 mm), in a drawn form."""

    lay: LayParams = LayParams()
    extra: WorldEffects = WorldEffects()
    form: FormParams = FormParams()
    sensors: SensorParams = SensorParams()
    name: ClassVar[str] = "dynamic"
    options: ClassVar[Options] = DEFAULTS
    own_effects: ClassVar[bool] = True

    @classmethod
    def for_case(cls, seed: int, index: int, variations: Iterable = (),
                 always_on: Iterable = (),
                 measurement: MeasurementParams = MeasurementParams(),
                 strata: int = 0) -> DynamicWorld:
        """The case's form: ``variations`` drawn on a random stream of its own
        (:func:`~rheo_shaping_validation.worlds.forms.case_form`; none drawn: the plain
        dynamic world)."""
        return cls(form=case_form(seed, index, variations, always_on, strata))

    def drawn(self, rng: random.Random, extra: WorldEffects) -> DynamicWorld:
        """With ``extra`` (its own effects) and a laying drawn from four numbers of ``rng``."""
        lay = draw_lay((rng.random(), rng.random(), rng.random(), rng.random()))
        return replace(self, lay=lay, extra=extra)

    def true_cell(self, cell: CellParams) -> CellParams:
        return cell

    def run(self, cell: CellParams, path) -> WorldRun:
        return run_world(cell, path, lay=self.lay, extra=self.extra, form=self.form)

    def measure(self, run, path, cell: CellParams, rng: np.random.Generator, chain: dict,
                name: str) -> Record:
        return measure_world(run, path, self.sensors, rng, chain, self.extra, name, self.form)

    @classmethod
    def true_n_masses(cls, n_masses: int) -> int:
        return WorldNumerics().n_masses

    def describe(self) -> dict:
        return {"lay": vars(self.lay), "form": self.form.as_dict()}


#: The worlds that make a benchmark's records (``diagnose-benchmark --world``), by name.
WORLDS: dict[str, type[FinerChain] | type[DynamicWorld]] = {
    FinerChain.name: FinerChain, DynamicWorld.name: DynamicWorld}


#: Both worlds are :class:`World` s (mypy checks the protocol here).
_IMPLEMENTS: tuple[World, ...] = (FinerChain(), DynamicWorld())


def check_world(world: str) -> str:
    """``world`` if it is one of :data:`WORLDS`, else ValueError naming them."""
    if world not in WORLDS:
        raise ValueError(f"unknown world {world!r}: expected one of {', '.join(WORLDS)}")
    return world
