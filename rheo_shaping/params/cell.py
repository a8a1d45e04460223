"""Parameters of a shaping cell: one schema for the core and the ROS nodes.

Dotted names (``material.k1``) are the ROS parameter names; the nested
frozen dataclasses are what the core takes.  Defaults are the paper's
material; the geometry the paper leaves open is chosen (and explained) in
``config/cell.yaml``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from .schema import ParameterError, param

INF = math.inf


@dataclass(frozen=True)
class MaterialParams:
    """Three-element material constants on the identification specimen."""

    k1: float = param(95.0, "spring k1 of the three-element unit on the specimen",
                      "N/m", 0.0, 1e6, lo_open=True)
    c1: float = param(0.0, "dashpot c1 parallel to k1 (0: Maxwell model)", "N s/m", 0.0, 1e8)
    c2: float = param(1.30e3, "series dashpot c2 (plastic flow); inf: no flow",
                      "N s/m", 0.0, None, lo_open=True)
    specimen_length: float = param(
        0.1, "rest length the constants belong to", "m", 0.0, 10.0, lo_open=True)
    F_break: float = param(
        1.04, "tension at crack initiation (0.05 m wide strip)", "N", 0.0, 1e3, lo_open=True)


@dataclass(frozen=True)
class SheetParams:
    """The sheet strip and its lumped-mass discretisation."""

    thickness: float = param(
        4e-3, "sheet thickness = diameter of the lumped spheres", "m", 0.0, 0.05, lo_open=True)
    width: float = param(0.05, "strip width the tensions refer to", "m", 0.0, 1.0, lo_open=True)
    mass_per_length: float = param(
        0.3125, "mass per unit rest length of the strip", "kg/m", 0.0, 100.0, lo_open=True)
    n_masses: int = param(63, "number of lumped masses (links = n_masses + 1)", "", 1, 2000)
    top_bond_x: float = param(-0.0175,
                              "x of the bond on the cake top (z = cake height)", "m", -10.0, 0.0)
    bottom_bond_x: float = param(
        0.0611, "x of the bond on the workplane (z = 0)", "m", 0.0, 10.0, lo_open=True)
    excess_length: float = param(
        0.0061, "rest length beyond the taut drape (catenary sag at t = 0)", "m", 0.0, 1.0)


@dataclass(frozen=True)
class CakeParams:
    """The mould: its 2-D cross-section (wall x = 0, top z = height)."""

    height: float = param(0.0576, "cake height", "m", 0.0, 2.0, lo_open=True)
    fillet_radius: float = param(0.0112, "radius of the rounded top edge", "m", 0.0, 1.0)
    radius: float = param(0.09, "cake radius (plots; the model is 2-D)",
                          "m", 0.0, 10.0, lo_open=True)


@dataclass(frozen=True)
class ToolParams:
    """Cross-section of the rigid shaping tool, relative to its reference point."""

    shape: str = param("rounded_rectangle", "tool cross-section", "",
                       choices=("circle", "rounded_rectangle", "polygon"))
    radius: float = param(0.01, "circle radius", "m", 0.0, 1.0, lo_open=True)
    width: float = param(0.04, "rounded rectangle width (x)", "m", 0.0, 1.0, lo_open=True)
    height: float = param(0.04, "rounded rectangle height (z)", "m", 0.0, 1.0, lo_open=True)
    corner_radius: float = param(
        0.0094, "rounding radius of the rectangle or polygon corners", "m", 0.0, 1.0)
    vertices: tuple = param([0.0, 0.0, 0.02, 0.0, 0.02, 0.04, 0.0, 0.04],
                            "polygon vertices x0, z0, x1, z1, ... "
                            "counter-clockwise", "m", -1.0, 1.0, min_length=2)
    home: tuple = param(
        [0.0345, 0.0595], "home position of the reference point (x, "
                          "z)", "m", -10.0, 10.0, length=2)


@dataclass(frozen=True)
class MovementParams:
    """Which shaping movement, and the timing the paper uses (Sec. 5)."""

    number: int = param(
        4, "paper movement 1 vertical, 2 horizontal, 3 inclined 45 deg, 4 two-step; 0: "
           "waypoints", "", 0, 4)
    speed: float = param(1e-3, "tool path speed", "m/s", 0.0, 0.1, lo_open=True)
    accel: float = param(5e-3, "tool path acceleration limit", "m/s^2", 0.0, 10.0, lo_open=True)
    jerk: float = param(5e-2, "tool path jerk limit", "m/s^3", 0.0, 1000.0, lo_open=True)
    process_time: float = param(120.0, "duration of the whole process",
                                "s", 0.0, 3600.0, lo_open=True)
    dwell: float = param(
        30.0, "stop at the end of travel (movements 1-3; movement 4 splits it in "
              "two)", "s", 0.0, 3600.0)
    retract_speed: float = param(1e-3, "tool speed when it returns home",
                                 "m/s", 0.0, 0.1, lo_open=True)
    d: float = param(
        0.0145, "movement 4: distance of the tool from the cake wall in its vertical "
                "step", "m", 0.0, 1.0)
    start_1: tuple = param(
        [0.0262, 0.0595], "movement 1 start (x, z) of the reference "
                          "point", "m", -10.0, 10.0, length=2)
    end_1: tuple = param([0.0262, 0.0241], "movement 1 end of travel (x, z)",
                         "m", -10.0, 10.0, length=2)
    start_2: tuple = param([0.0616, 0.0241], "movement 2 start (x, z)", "m", -10.0, 10.0, length=2)
    end_2: tuple = param([0.0262, 0.0241], "movement 2 end of travel (x, z)",
                         "m", -10.0, 10.0, length=2)
    start_3: tuple = param([0.0512, 0.0491], "movement 3 start (x, z)", "m", -10.0, 10.0, length=2)
    end_3: tuple = param([0.0262, 0.0241], "movement 3 end of travel (x, z)",
                         "m", -10.0, 10.0, length=2)
    start_4: tuple = param(
        [0.0262, 0.0595], "movement 4 start (x, z); its x is replaced by "
                          "d", "m", -10.0, 10.0, length=2)
    end_4: tuple = param(
        [0.0262, 0.0241], "movement 4 end of travel (x, z); the vertical step ends at this "
                          "z", "m", -10.0, 10.0, length=2)
    waypoints: tuple = param([0.0345, 0.0241, 0.0262, 0.0241],
                             "movement 0: waypoints x0, z0, x1, z1, ... after "
                             "home", "m", -10.0, 10.0, min_length=2)
    dwells: tuple = param([15.0, 15.0], "movement 0: stop after each waypoint",
                          "s", 0.0, 3600.0, min_length=1)


@dataclass(frozen=True)
class SolverParams:
    """Numerics of the sheet model (see docs/model.md for the choice)."""

    gravity: float = param(9.81, "gravitational acceleration (-z)", "m/s^2", 0.0, 100.0)
    settle_time: float = param(
        1.0, "sagging under gravity with inertia before the process starts (test case "
             "1)", "s", 0.0, 3600.0)
    dt_settle: float = param(2e-3, "time step of the inertial settling",
                             "s", 0.0, 1.0, lo_open=True)
    dt: float = param(0.5, "largest quasi-static time step while the tool moves",
                      "s", 0.0, 100.0, lo_open=True)
    dt_still: float = param(
        2.0, "largest quasi-static time step while the tool stands "
             "still", "s", 0.0, 100.0, lo_open=True)
    max_tool_step: float = param(5e-4, "largest tool travel in one step",
                                 "m", 0.0, 0.01, lo_open=True)
    contact_stiffness: float = param(
        1e7, "penalty stiffness of the unilateral contacts", "N/m", 1.0, 1e12)
    force_tol: float = param(1e-8, "Newton tolerance on the force residual",
                             "N", 0.0, 1e-2, lo_open=True)
    max_newton: int = param(50, "Newton iterations allowed per step", "", 1, 1000)


@dataclass(frozen=True)
class EffectsParams:
    """Effects the nominal model leaves out (sim-to-real diagnosis, docs/diagnosis.md).

    Every one is off at its default; the names are the effects' names in the
    YAML and in every diagnosis report (:mod:`rheo_shaping.sheet.effects`).
    """

    friction_mould: float = param(
        0.0, "Coulomb friction coefficient between sheet and mould (cake and workplane); 0: "
             "off", "", 0.0, 2.0)
    friction_tool: float = param(
        0.0, "Coulomb friction coefficient between sheet and tool; 0: off", "", 0.0, 2.0)
    bending: float = param(
        0.0, "bending stiffness EI of the strip (its width); 0: off (pin "
             "joints)", "N m^2", 0.0, 1e-2)
    kelvin_c1: float = param(
        0.0, "dashpot c1 added parallel to k1 on the specimen (Kelvin-Voigt retardation); 0: "
             "off", "N s/m", 0.0, 1e6)
    power_law: float = param(
        1.0, "flow index n of a power-law (shear-thinning) dashpot c2: plastic rate ~ "
             "(F/F_ref)^(1/n) F/c2; 1: off (Newtonian)", "", 0.1, 1.0)
    power_law_ref_tension: float = param(
        0.5, "tension F_ref at which the power-law dashpot equals "
             "c2", "N", 0.0, 100.0, lo_open=True)
    thinning: float = param(
        0.0, "exponent b of the sheet's thinning under plastic stretch: a link's constants scale "
             "by (L/(L+p))^b; 0: off", "", 0.0, 3.0)
    tool_offset: tuple = param(
        [0.0, 0.0], "offset (x, z) of the real tool from its measured (commanded) pose; (0, 0): "
                    "off", "m", -0.05, 0.05, length=2)
    mass_error: float = param(
        0.0, "relative error of the mass per length: the real sheet weighs nominal x (1 + value); "
             "0: off", "", -0.9, 10.0)


#: Most time steps one phase of a run may need (a step of 5e-324 s is inside its range but
#: would never end): beyond, the cell is refused with the figures.
MAX_STEPS = 10_000_000


@dataclass(frozen=True)
class CellParams:
    """Everything that shapes a run of the cell."""

    material: MaterialParams = field(default_factory=MaterialParams)
    sheet: SheetParams = field(default_factory=SheetParams)
    cake: CakeParams = field(default_factory=CakeParams)
    tool: ToolParams = field(default_factory=ToolParams)
    movement: MovementParams = field(default_factory=MovementParams)
    solver: SolverParams = field(default_factory=SolverParams)
    effects: EffectsParams = field(default_factory=EffectsParams)

    def _check_step_counts(self) -> None:
        """Refuse solver steps so small that a run would not end (:data:`MAX_STEPS`)."""
        sp, mv = self.solver, self.movement
        for name, count, what in (
                ("solver.dt_settle", sp.settle_time / sp.dt_settle, "settle_time"),
                ("solver.dt_still", mv.process_time / sp.dt_still, "movement.process_time"),
                ("solver.dt", mv.process_time / sp.dt, "movement.process_time"),
                ("solver.max_tool_step", max(mv.speed, mv.retract_speed) * mv.process_time
                 / sp.max_tool_step, "the tool's travel at its speed over process_time")):
            if count > MAX_STEPS:
                value = getattr(sp, name.split(".")[1])
                raise ParameterError(
                    f"parameter '{name}' = {value!r} is invalid: {what} would take {count:.3g} "
                    f"steps; expected at most {MAX_STEPS:g} (a larger step)")

    def __post_init__(self) -> None:
        s, c = self.sheet, self.cake
        if not s.thickness / 2 > 0.0:
            raise ParameterError(
                f"parameter 'sheet.thickness' = {s.thickness!r} is invalid: expected a value "
                "whose half (the masses' contact radius) is > 0 m")
        self._check_step_counts()
        for name in ("k1", "c2"):
            value = getattr(self.material, name)
            if value > 0 and not math.isfinite(1.0 / value):
                raise ParameterError(
                    f"parameter 'material.{name}' = {value!r} is invalid: expected a value whose "
                    f"inverse is finite (the link's compliance)")
        if s.top_bond_x > -c.fillet_radius:
            raise ParameterError(
                f"parameter 'sheet.top_bond_x' = {s.top_bond_x!r} is invalid: expected a value "
                f"<= -cake.fillet_radius = {-c.fillet_radius:g} m (the bond lies on the flat top)")
        if s.bottom_bond_x < s.thickness:
            raise ParameterError(
                f"parameter 'sheet.bottom_bond_x' = {s.bottom_bond_x!r} is invalid: expected a "
                "value "
                f">= sheet.thickness = {s.thickness:g} m (the bond lies on the workplane beside "
                "the wall)")


def batch_cell(cell: CellParams, k1: float = 1.0, c2: float = 1.0, mass: float = 1.0,
               friction_mould: float | None = None,
               friction_tool: float | None = None) -> CellParams:
    """``cell`` with a batch's material: k1 [N/m], c2 [N s/m] and the sheet's mass per
    length [kg/m] each a multiple [-] of ``cell``'s (a batch differs from its params file),
    and the Coulomb friction coefficients [-] of mould and tool when given."""
    effects = cell.effects
    if friction_mould is not None:
        effects = replace(effects, friction_mould=float(friction_mould))
    if friction_tool is not None:
        effects = replace(effects, friction_tool=float(friction_tool))
    return replace(cell, material=replace(cell.material, k1=cell.material.k1 * k1,
                                          c2=cell.material.c2 * c2),
                   sheet=replace(cell.sheet, mass_per_length=cell.sheet.mass_per_length * mass),
                   effects=effects)
