"""The effects library: what the nominal sheet model leaves out.

Each effect is an optional, parameterised extension of the simulator, off by
default and switched on in the params YAML's ``effects`` section
(:class:`~rheo_shaping.params.cell.EffectsParams`).  Its name is the same in the
YAML, in this registry and in every diagnosis report.  The diagnosis fits an
effect's ``fit`` parameters inside ``bounds``; the diagnosis benchmark draws
true magnitudes from ``realistic`` (docs/diagnosis.md lists them beside the naming
rule's prior ranges).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Sequence

from ..params.cell import CellParams, EffectsParams
from .chain import SheetEffects


@dataclass(frozen=True)
class Effect:
    """One unmodelled effect and how the diagnosis fits it."""

    name: str
    description: str
    fit: tuple[str, ...]                       # names of its fitted parameters (labels)
    unit: tuple[str, ...]
    off: tuple[float, ...]                     # values that switch it off
    bounds: tuple[tuple[float, float], ...]    # fit range per parameter
    realistic: tuple[tuple[float, float], ...]  # magnitude range of real cells (benchmark draws;
    # tool_offset and mass_error: |value|, random sign)

    @property
    def n_params(self) -> int:
        return len(self.fit)

    def apply(self, params: CellParams, values: Sequence[float]) -> CellParams:
        """``params`` with this effect set to ``values`` (one per fitted parameter)."""
        values = tuple(float(v) for v in values)
        if len(values) != self.n_params:
            raise ValueError(f"effect '{self.name}' takes {self.n_params} value(s) "
                             f"({', '.join(self.fit)}), got {len(values)}")
        eff = params.effects
        if self.name == "tool_offset":
            eff = replace(eff, tool_offset=values)
        else:
            # a float field named at run time: mypy cannot pair the name with its type
            change: dict[str, Any] = {self.name: values[0]}
            eff = replace(eff, **change)
        return replace(params, effects=eff)

    def value(self, params: CellParams) -> tuple[float, ...]:
        """This effect's current parameter values in ``params``."""
        v = getattr(params.effects, self.name)
        return tuple(float(x) for x in v) if isinstance(v, tuple) else (float(v),)

    def is_on(self, params: CellParams) -> bool:
        return self.value(params) != self.off


EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect("friction_mould", "Coulomb friction between the sheet and the mould (cake, workplane)",
           ("mu",), ("",), (0.0,), ((0.0, 1.2),), ((0.2, 0.6),)),
    Effect("friction_tool", "Coulomb friction between the sheet and the tool",
           ("mu",), ("",), (0.0,), ((0.0, 1.2),), ((0.2, 0.6),)),
    Effect("bending", "bending stiffness of the sheet (the model has pin joints)",
           ("EI",), ("N m^2",), (0.0,), ((0.0, 3e-5),), ((2e-6, 1e-5),)),
    Effect("kelvin_c1", "a dashpot c1 parallel to k1 (delayed elasticity; the model is Maxwell)",
           ("c1",), ("N s/m",), (0.0,), ((0.0, 5000.0),), ((300.0, 2000.0),)),
    Effect("power_law", "a shear-thinning (power-law) dashpot c2 (the model's is Newtonian)",
           ("n",), ("",), (1.0,), ((0.3, 1.0),), ((0.5, 0.8),)),
    Effect("thinning", "the sheet thins where it flows, its links soften",
           ("b",), ("",), (0.0,), ((0.0, 3.0),), ((0.5, 2.0),)),
    Effect("tool_offset", "the tool is not where the robot says (calibration offset)",
           ("dx", "dz"), ("m", "m"), (0.0, 0.0), ((-4e-3, 4e-3), (-4e-3, 4e-3)),
           ((0.7e-3, 2e-3), (0.7e-3, 2e-3))),
    Effect("mass_error", "the sheet is heavier or lighter than the scenario says",
           ("fraction",), ("",), (0.0,), ((-0.5, 1.0),), ((0.15, 0.4),)),
)}

#: The names, in the order of EffectsParams' fields.
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)


def active_effects(params: CellParams) -> list[str]:
    """Names of the effects switched on in ``params``."""
    return [name for name, e in EFFECTS.items() if e.is_on(params)]


def nominal(params: CellParams) -> CellParams:
    """``params`` with every effect off (the nominal model)."""
    return replace(params, effects=replace(EffectsParams(),
                                           power_law_ref_tension=(
                                               params.effects.power_law_ref_tension)))


def sheet_effects(params: CellParams) -> SheetEffects:
    """The sheet model's optional physics from ``params.effects`` (rheo_shaping.sheet.effects)."""
    e = params.effects
    return SheetEffects(
        friction=(("cake", e.friction_mould), ("workplane",
                  e.friction_mould), ("tool", e.friction_tool)),
        bending=e.bending, power_law_n=e.power_law, power_law_ref=e.power_law_ref_tension,
        thinning=e.thinning, tool_shift=tuple(e.tool_offset))
