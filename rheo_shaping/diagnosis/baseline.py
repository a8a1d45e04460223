"""What a careful user knows only within a tolerance: the baseline the diagnosis calibrates.

Two kinds of baseline parameter, each fitted in units of its tolerance
(u = (value - written value) / tolerance):

* :data:`SHEET` (cell side, each needs a simulation per Jacobian column):
  the material constants within their identification intervals, the mass per
  length (weighed), the bond positions, the sheet's initial sag (how it was
  laid: ``sheet.excess_length``), the cake geometry within what a ruler
  gives (+-1 mm), and the contact's stiffness (a sponge cake, a soft tool pad: on a log
  scale, u = 0, where the diagnosis starts, three decades softer than the written, rigid
  penalty, u = 1 six).  Bounded to ``lower <= u <= upper`` (-1 <= u <= 1: the written
  value +- tolerance; the contact 0 <= u <= 1, only softer than the start).
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
    lower: float = -1.0   # the sheet knob's box in units of the tolerance: lower <= u <= upper
    upper: float = 1.0
    log: bool = False     # value = written x 10**(offset + u x tolerance), both in decades
    offset: float = 0.0


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
    Knob("solver.contact_stiffness", -3.0, "decades", log=True, offset=-3.0, lower=0.0,
         description="contact stiffness of the mould and the tool [N/m]: three decades "
                     "softer than the written (rigid) penalty at u 0, six at u 1 (a sponge "
                     "cake, a soft pad)"),
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

#: The sheet knobs known within a tolerance either side of their written value (a
#: benchmark's cell draws its truth within these); the contact's stiffness is written as
#: rigid and may only be softer.
SYMMETRIC: tuple[Knob, ...] = tuple(k for k in SHEET if not k.log)

#: How the sheet knobs are taken (:class:`.options.BaselineMode`): fitted within their
#: tolerances, or held as written (the scenario is a calibrated cell; the measurement chain
#: is fitted either way).
BASELINE_MODES: tuple[str, ...] = tuple(m.value for m in BaselineMode)


def written(params: CellParams, name: str) -> float:
    """The value of sheet knob ``name`` in ``params``."""
    section, field = name.split(".")
    return float(getattr(getattr(params, section), field))


def step_of(params: CellParams, knob: Knob, base: CellParams | None = None) -> float:
    """One tolerance of ``knob`` in its unit (relative ones of the written value in ``base``;
    a log knob's in decades)."""
    ref = params if base is None else base
    return knob.tolerance * abs(written(ref, knob.name)) if knob.relative else knob.tolerance


def value_at(ref: CellParams, knob: Knob, u: float) -> float:
    """Sheet knob ``knob``'s value [its unit] ``u`` tolerances from its written value in
    ``ref`` (a log knob: the written value times 10**(offset + u x tolerance))."""
    if knob.log:
        return written(ref, knob.name) * 10.0 ** (knob.offset + u * knob.tolerance)
    return written(ref, knob.name) + u * step_of(ref, knob)


def sheet_box(scale: float = 1.0):
    """The sheet knobs' bounds (lower, upper) [tolerances], each knob's box times ``scale``
    (0: held as written)."""
    import numpy as np
    return (scale * np.array([k.lower for k in SHEET]),
            scale * np.array([k.upper for k in SHEET]))


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
        value = value_at(ref, knob, u[knob.name])
        out = replace(out, **{section: replace(getattr(out, section), **{field: value})})
    return out


def moves(knob: Knob, sheet_lim: float) -> bool:
    """Whether ``knob`` leaves its written value: every sheet knob while the sheet is fitted
    (``sheet_lim`` > 0); held as written (0), a log knob's offset, the fit's start, is not
    applied either."""
    return sheet_lim > 0 or not knob.log


def reference(params: CellParams, sheet_lim: float = 1.0) -> CellParams:
    """The cell at u = 0 of every sheet knob, where the diagnosis starts: ``params`` as
    written but for the log knobs' offsets (the contact three decades softer); with the
    sheet held as written (``sheet_lim`` 0), ``params`` itself (:func:`moves`)."""
    return with_sheet(params, {k.name: 0.0 for k in SHEET if k.log and moves(k, sheet_lim)})


def values(params: CellParams, u: dict[str, float],
           sheet_lim: float = 1.0) -> dict[str, float]:
    """Physical values [knob unit] of the sheet knobs at ``u`` (and the chain's: u x tolerance);
    with the sheet held (``sheet_lim`` 0) the log knobs are as written."""
    out = {}
    for knob in SHEET:
        out[knob.name] = (value_at(params, knob, u.get(knob.name, 0.0))
                          if moves(knob, sheet_lim) else written(params, knob.name))
    for knob in CHAIN:
        out[knob.name] = u.get(knob.name, 0.0) * knob.tolerance
    return out
