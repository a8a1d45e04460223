"""Parameters of the dynamic world: its numerics, how the sheet was laid, and the effects
it holds that the diagnosis's library does not (frozen dataclasses, SI units).

The library's effects (friction on mould and tool, bending, Kelvin c1, power law,
thinning, tool offset, mass error) are read from ``CellParams.effects`` with the
same names and meanings as the sheet model's (docs/diagnosis.md); the world
implements each of them itself (:mod:`rheo_shaping_validation.worlds.kernel`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any, Sequence


@dataclass(frozen=True)
class WorldNumerics:
    """How the world is discretised and integrated."""

    n_masses: int = 63                 # point masses of the chain (links: n_masses + 1)
    dt: float = 1e-3                   # s, the linearly implicit Euler step
    dt_release: float = 2.5e-4         # s, the step while the released sheet falls
    #: s, the step when Coulomb friction acts (friction_mould or friction_tool > 0): at dt
    #: the stick springs of a rigid tool put movement 3's tool force 49 mN RMS off an eighth
    #: of dt, at this quarter 9 mN (first order; the load cell's noise is 5 mN); without
    #: friction under 0.1 mN
    dt_friction: float = 2.5e-4
    release_time: float = 1.0          # s, how long the release's finer steps last
    reference_pitch: float = 1.65e-3   # m, finer chains scale both steps by pitch / this
    contact_modulus: float = 5e7       # N/m per m of sheet: penalty stiffness = modulus x pitch
    contact_damping: float = 0.5       # damping ratio of a mass on its contact spring
    stick_ratio: float = 1.0           # tangential (stick) stiffness / normal stiffness
    air_damping: float = 3.0           # 1/s, damping of the masses' absolute velocity
    output_rate: float = 50.0          # Hz, samples kept (forces: the mean over the interval)

    def __post_init__(self) -> None:
        if self.n_masses < 3:
            raise ValueError(f"n_masses = {self.n_masses!r}: expected at least 3")
        for name in ("dt", "dt_release", "dt_friction", "contact_modulus", "output_rate",
                     "reference_pitch"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} = {v!r}: expected a finite number > 0")
        if self.output_rate * max(self.dt, self.dt_release) > 1.0 + 1e-9:
            raise ValueError(f"output_rate = {self.output_rate!r} Hz is above 1/dt")


@dataclass(frozen=True)
class LayParams:
    """How the sheet was laid on the cake before its release at t = 0.

    The sheet lies flat on the cake top and round its edge; its free part, of the
    scenario's length (the taut chord plus ``sheet.excess_length``), is held in the
    shape w(u) = A (sin(pi u) + mode2 sin(2 pi u)) off its chord (u in 0-1 from the
    edge to the workplane bond, A > 0 toward gravity, solved for the length), raised
    by ``lift`` [m] off the cake (top and edge), and laid with a ``prestrain``
    (links' rest length = laid length / (1 + prestrain)).  Released from rest at t = 0:
    the hands let go over ``let_go`` [s] (the sheet's weight comes on linearly).
    """

    mode2: float = 0.0        # second sine mode of the free part's shape, relative to the first
    lift: float = 0.0         # m, height the sheet is held above the cake top and edge
    prestrain: float = 0.0    # strain the sheet was laid with (negative: laid loose)
    let_go: float = 0.3       # s, how long the release takes

    def __post_init__(self) -> None:
        if not -1.0 <= self.mode2 <= 1.0:
            raise ValueError(f"mode2 = {self.mode2!r}: expected -1 to 1")
        if not 0.0 <= self.lift <= 5e-3:
            raise ValueError(f"lift = {self.lift!r} m: expected 0 to 5e-3 m")
        if not -0.02 <= self.prestrain <= 0.02:
            raise ValueError(f"prestrain = {self.prestrain!r}: expected -0.02 to 0.02")
        if not 0.0 <= self.let_go <= 1.0:
            raise ValueError(f"let_go = {self.let_go!r} s: expected 0 to 1 s")


@dataclass(frozen=True)
class WorldEffects:
    """Effects of the world outside the diagnosis's library (0: off).

    * ``strain_hardening`` beta [-]: the spring stiffens with the link's total
      strain, k1 (1 + beta max(strain, 0)) (material);
    * ``adhesion`` [N/m]: a sticky mould pulls the sheet with this force per unit
      length while it is within ``adhesion_range`` of cake or workplane, falling
      linearly to 0 at the range, and where it touches holds it against sliding with
      the same force per length on top of any Coulomb friction (boundary);
    * ``tool_tilt`` [rad]: the tool's cross-section is rotated about its reference
      point (boundary; not drawn by the benchmark: at the paper's end of travel the
      tool's bottom clears the sheet on the workplane by 0.1 mm, so a tilt beyond
      0.005 rad pinches it, 10 N on this world's hard spheres, and one below shows
      less than the noise);
    * ``tool_lag`` [s]: the robot's tool follows the pose it reports that much later
      (a servo lag; the record's pose is the commanded one) (boundary);
    * ``camera_scale`` [-]: the vision system's scale is off: measured points are
      (1 + value) times their distance from ``camera_centre`` (sensor);
    * ``load_cell_drift`` [N/s]: the load cell's bias grows linearly in time along
      ``drift_direction`` (x, z) (sensor).
    """

    strain_hardening: float = 0.0
    adhesion: float = 0.0
    tool_tilt: float = 0.0
    tool_lag: float = 0.0
    camera_scale: float = 0.0
    load_cell_drift: float = 0.0
    adhesion_range: float = 5e-4            # m
    camera_centre: tuple = (0.02, 0.03)     # m, frame cake
    drift_direction: tuple = (0.0, 1.0)

    def with_value(self, name: str, value: float) -> "WorldEffects":
        """This set with effect ``name`` at ``value``."""
        if name not in WORLD_EFFECT_NAMES:
            raise ValueError(f"unknown world effect {name!r}: expected one of "
                             f"{', '.join(WORLD_EFFECT_NAMES)}")
        # a float field named at run time: mypy cannot pair the name with its type
        change: dict[str, Any] = {name: float(value)}
        return replace(self, **change)

    def active(self) -> list[str]:
        """Names of the effects switched on (``tool_tilt`` included)."""
        return [f.name for f in fields(self) if f.name in WORLD_EFFECT_NAMES + ("tool_tilt",)
                and getattr(self, f.name) != 0.0]


@dataclass(frozen=True)
class WorldEffect:
    """One effect the library does not hold: its kind and a realistic magnitude range."""

    name: str
    kind: str                               # material, boundary or sensor
    unit: str
    realistic: tuple[float, float]          # |value| range of real cells (benchmark draws)
    signed: bool                            # the benchmark draws a random sign
    cause: str                              # its kind in the diagnosis signature's causes

    def draw(self, rng) -> float:
        """A realistic value (``rng``: a ``random.Random``)."""
        v = rng.uniform(*self.realistic)
        return v * rng.choice((-1.0, 1.0)) if self.signed else v


WORLD_EFFECTS: dict[str, WorldEffect] = {e.name: e for e in (
    WorldEffect("strain_hardening", "material", "", (0.5, 2.0), False,
                "strain-dependent material"),
    WorldEffect("adhesion", "boundary", "N/m", (2.0, 6.0), False, "contact friction"),
    WorldEffect("tool_lag", "boundary", "s", (0.2, 0.5), False, "tool position calibration"),
    WorldEffect("camera_scale", "sensor", "", (0.01, 0.03), True, "measurement chain"),
    WorldEffect("load_cell_drift", "sensor", "N/s", (3e-4, 1e-3), True, "measurement chain"),
)}
WORLD_EFFECT_NAMES: tuple[str, ...] = tuple(WORLD_EFFECTS)


def draw_lay(u: Sequence[float]) -> LayParams:
    """A laying from four uniform numbers in [0, 1): mode2 in +-0.5, lift 0-1.5 mm,
    prestrain +-0.3 %, let go over 0.2-0.6 s."""
    a, b, c, d = (float(x) for x in u)
    return LayParams(mode2=-0.5 + a, lift=1.5e-3 * b, prestrain=-3e-3 + 6e-3 * c,
                     let_go=0.2 + 0.4 * d)
