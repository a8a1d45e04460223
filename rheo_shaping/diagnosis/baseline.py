"""What a careful user knows only within a tolerance: the baseline the diagnosis calibrates.

Two kinds of baseline parameter, each fitted in units of its tolerance
(u = (value - written value) / tolerance):

* :data:`SHEET` (cell side, each needs a simulation per Jacobian column):
  the material constants within their identification intervals, the mass per
  length (weighed), the bond positions, the sheet's initial sag (how it was
  laid: ``sheet.excess_length``) and the cake geometry within what a ruler
  gives (+-1 mm).  Bounded to |u| <= 1: the written value +- tolerance.
* :data:`CHAIN` (measurement side, linear in the residuals, no simulation):
  the vision system's offset (x, z), the load cell's bias (x, z), gain and
  time lag.  Fitted within the wider ``limit`` (so a chain error beyond its
  tolerance is seen, and reported as the chain's, not the sheet's).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from ..params.cell import CellParams
from .options import BaselineMode


@dataclass(frozen=True)
class Knob:
    """One baseline parameter: its dotted name, tolerance and (chain) fit limit."""

    name: str
    tolerance: float      # in the unit below; relative (fraction) when ``relative``
    unit: str
    relative: bool = False
    limit: float = 1.0    # fit bound in units of the tolerance
    description: str = ""


SHEET: tuple[Knob, ...] = (
    Knob("material.k1", 0.10, "N/m", True,
         description="spring k1 (identification interval +-10 %)"),
    Knob("material.c2", 0.15, "N s/m", True,
         description="dashpot c2 (identification interval +-15 %)"),
    Knob("sheet.mass_per_length", 0.03, "kg/m", True,
         description="mass per length (weighed, +-3 %)"),
    Knob("sheet.top_bond_x", 1e-3, "m", description="bond on the cake top (ruler, +-1 mm)"),
    Knob("sheet.bottom_bond_x", 1e-3, "m", description="bond on the workplane (ruler, +-1 mm)"),
    Knob("sheet.excess_length", 1e-3, "m", description="initial sag: rest length beyond the taut "
         "drape (how the sheet was laid, +-1 mm)"),
    Knob("cake.height", 1e-3, "m", description="cake height (ruler, +-1 mm)"),
    Knob("cake.fillet_radius", 1e-3, "m", description="radius of the cake's top edge (+-1 mm)"),
)

CHAIN: tuple[Knob, ...] = (
    Knob("vision.dx", 5e-4, "m", limit=10.0, description="vision system offset in x"),
    Knob("vision.dz", 5e-4, "m", limit=10.0, description="vision system offset in z"),
    Knob("load_cell.bias_x", 0.01, "N", limit=30.0, description="load cell bias in x"),
    Knob("load_cell.bias_z", 0.01, "N", limit=30.0, description="load cell bias in z"),
    Knob("load_cell.gain", 0.03, "", limit=10.0, description="load cell gain error (fraction)"),
    Knob("load_cell.lag", 0.05, "s", limit=10.0, description="load cell time lag behind the pose"),
)

KNOBS: dict[str, Knob] = {k.name: k for k in SHEET + CHAIN}

#: How the sheet knobs are taken (:class:`.options.BaselineMode`): fitted within their
#: tolerances, or held as written (the scenario is a calibrated cell; the measurement chain
#: is fitted either way).
BASELINE_MODES: tuple[str, ...] = tuple(m.value for m in BaselineMode)


def written(params: CellParams, name: str) -> float:
    """The value of sheet knob ``name`` in ``params``."""
    section, field = name.split(".")
    return float(getattr(getattr(params, section), field))


def step_of(params: CellParams, knob: Knob, base: CellParams | None = None) -> float:
    """One tolerance of ``knob`` in its unit (relative ones of the written value in ``base``)."""
    ref = params if base is None else base
    return knob.tolerance * abs(written(ref, knob.name)) if knob.relative else knob.tolerance


def with_sheet(params: CellParams, u: dict[str, float],
               base: CellParams | None = None) -> CellParams:
    """``params`` with each sheet knob moved by ``u[name]`` tolerances from ``base`` (default:
    itself)."""
    ref = params if base is None else base
    out = params
    for knob in SHEET:
        if knob.name not in u:
            continue
        section, field = knob.name.split(".")
        value = written(ref, knob.name) + u[knob.name] * step_of(ref, knob)
        out = replace(out, **{section: replace(getattr(out, section), **{field: value})})
    return out


def values(params: CellParams, u: dict[str, float]) -> dict[str, float]:
    """Physical values [knob unit] of the sheet knobs at ``u`` (and the chain's: u x tolerance)."""
    out = {}
    for knob in SHEET:
        out[knob.name] = written(params, knob.name) + u.get(knob.name, 0.0) * step_of(params, knob)
    for knob in CHAIN:
        out[knob.name] = u.get(knob.name, 0.0) * knob.tolerance
    return out
