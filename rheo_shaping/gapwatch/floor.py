"""The floor of the gap watch: how large the residual of a cell the model fits may be.

A :class:`ResidualFloor` holds, per observable, the largest residual in noise units
(RMS / noise, 1 = noise only) that a run the model fits still shows: over a
sliding window (``*_window_z``) and over the run so far (``*_run_z``).  Above
it, for a sustained time, the gap watch says WARN.  The shipped floor
(``rheo_shaping/data/gapwatch_floor.json``) is calibrated on nominal runs of
this package's simulator with the measurement model on
(``benchmarks/gapwatch_floor.py`` regenerates it); a model-form floor from the
diagnosis (issue 26) can replace it: any JSON file with these fields, loaded
with :meth:`ResidualFloor.load` (the node's ``floor_file``, the benchmarks' ``--floor``).
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

#: The floor shipped with the package.
DEFAULT_FLOOR = Path(__file__).resolve().parents[1] / "data" / "gapwatch_floor.json"


class ResidualFloorError(ValueError):
    """A floor file that cannot be used (named with the field, value and what was expected)."""


@dataclass(frozen=True)
class ResidualFloor:
    """Largest residuals (noise units) of runs the model fits, and what they were measured on."""

    profile_window_z: float      # profile RMS / noise over the window, largest on the floor's runs
    force_window_z: float        # tool force RMS / noise over the window
    profile_run_z: float         # the same over the run so far
    force_run_z: float
    window_s: float              # s, the window the *_window_z were measured over
    delta_bias_m: float = 0.0    # m, median (Delta of the measured frame - the model's) of the
    # floor's runs: the bias of the measured Delta (noisy points reach lower x)
    source: str = ""             # what the floor was calibrated on (runs, seeds, command)
    runs: int = 0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            ok = isinstance(v, (int, float)) and math.isfinite(v) and v >= 1.0
            if f.name.endswith("_z") and not ok:
                raise ResidualFloorError(
                    f"floor field '{f.name}' = {v!r} is invalid: expected a finite number "
                    f">= 1 (residual RMS in units of the noise)")
        if not (math.isfinite(self.window_s) and self.window_s > 0):
            raise ResidualFloorError(f"floor field 'window_s' = {self.window_s!r} is invalid: "
                                     f"expected a window > 0 s")

    @classmethod
    def load(cls, path: str | Path | None = None) -> "ResidualFloor":
        """The floor in ``path`` (JSON; default: the shipped one)."""
        p = Path(path) if path else DEFAULT_FLOOR
        try:
            data = json.loads(p.read_text())
        except OSError as exc:
            raise ResidualFloorError(
                f"floor file '{p}': cannot read it ({exc.strerror})") from None
        except json.JSONDecodeError as exc:
            raise ResidualFloorError(f"floor file '{p}': not JSON ({exc})") from None
        if not isinstance(data, dict):
            raise ResidualFloorError(f"floor file '{p}': expected a JSON object, got "
                                     f"{type(data).__name__}")
        data = data.get("floor", data)
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - names)
        missing = sorted(f.name for f in fields(cls)
                         if f.name not in data and f.name.endswith(("_z", "_s")))
        if unknown or missing:
            what = (f"unknown field '{unknown[0]}'" if unknown
                    else f"field '{missing[0]}' missing")
            raise ResidualFloorError(f"floor file '{p}': {what}; expected "
                                     f"{', '.join(sorted(names))}")
        try:
            return cls(**data)
        except TypeError as exc:
            raise ResidualFloorError(f"floor file '{p}': {exc}") from None
        except ResidualFloorError as exc:
            raise ResidualFloorError(f"floor file '{p}': {exc}") from None

    def dump(self, path: str | Path, extra: dict | None = None) -> None:
        """Write the floor (and ``extra``, e.g. the calibration's figures) as JSON."""
        out = {"floor": asdict(self)}
        if extra:
            out.update(extra)
        Path(path).write_text(json.dumps(out, indent=1) + "\n")
