"""The monitor's abort threshold budget (safety principle 4, docs/safety-principles.md), from
the core.

With r the largest tension rate the cell can reach, t_detect the time from a
tension sample to the planner's reaction and t_stop the tool's jerk-limited
stopping time, a threshold that still stops the tool before the sheet breaks
satisfies

    F_abort <= F_break - r (t_detect + t_stop) - 3 sigma.

:func:`abort_budget` runs the paper's movements 1-4 at their nominal speed and
faster (default up to 5x), takes r as the largest rate of rise of the largest
link tension in those runs and t_stop as the stopping time from the fastest
of those speeds (:func:`rheo_shaping.planning.stopping.stopping_time`), and returns the
bound on ``abort_ratio = F_abort / F_break``.  Each row's own bound (its r
with its own speed's t_stop) is reported too.  ``python -m
rheo_shaping.safety.abort_budget [--params FILE]`` prints the table that docs/ros.md
quotes.  No ROS imports here.
"""
from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from ..params.cell import CellParams
from ..params.schema import ParameterError
from ..planning.plans import MotionLimits
from ..planning.movement import run_movement
from ..planning.stopping import stopping_time

#: Budgeted reaction time [s]: 20 Hz tension data (0.05 s), transport and
#: the monitor's and planner's reaction (one 50 Hz control period and margin).
DEFAULT_T_DETECT = 0.1
#: Tension noise [N] (1 sigma) assumed for a real cell's load cell; the
#: simulator's data are noise-free.
DEFAULT_SIGMA = 0.005


@dataclass(frozen=True)
class RateRow:
    """One run: movement, speed factor, tool speed [m/s], F_max [N], r [N/s], t_stop [s]."""

    movement: int
    speed_factor: float
    speed: float
    F_max: float
    r: float
    t_stop: float

    def margin(self, t_detect: float) -> float:
        """Tension [N] this run can add between a threshold crossing and rest."""
        return self.r * (t_detect + self.t_stop)


@dataclass(frozen=True)
class AbortBudget:
    """Lesson 4 with numbers from the core (SI units)."""

    F_break: float
    r: float                 # largest tension rate over all rows, N/s
    t_detect: float          # s
    t_stop: float            # s, stopping time at the fastest speed
    sigma: float             # N
    rows: tuple[RateRow, ...]

    @property
    def F_abort_max(self) -> float:
        """F_break - r (t_detect + t_stop) - 3 sigma [N] (worst rate with the longest stop)."""
        return self.F_break - self.r * (self.t_detect + self.t_stop) - 3.0 * self.sigma

    @property
    def ratio_max(self) -> float:
        """Largest safe ``abort_ratio`` by :attr:`F_abort_max`."""
        return self.F_abort_max / self.F_break

    @property
    def ratio_max_per_row(self) -> float:
        """Largest safe ratio when each run's rate is paired with its own stopping time."""
        worst = max(row.margin(self.t_detect) for row in self.rows)
        return (self.F_break - worst - 3.0 * self.sigma) / self.F_break

    def table(self) -> str:
        """The rows and the bound as Markdown."""
        lines = ["| movement | speed | F_max [N] | r [N/s] | t_stop [s] | r (t_detect + t_stop) "
                 "[N] |",
                 "|---|---|---|---|---|---|"]
        for row in self.rows:
            lines.append(f"| {row.movement} | {row.speed_factor:g}x = {row.speed * 1e3:g} mm/s | "
                         f"{row.F_max:.3f} | {row.r:.3f} | {row.t_stop:.2f} | "
                         f"{row.margin(self.t_detect):.3f} |")
        lines += ["",
                  f"F_break = {self.F_break:g} N, r = {self.r:.3f} N/s, t_detect = "
                  f"{self.t_detect:g} s, "
                  f"t_stop = {self.t_stop:.2f} s, sigma = {self.sigma:g} N",
                  f"F_abort <= {self.F_break:g} - {self.r:.3f} x ({self.t_detect:g} + "
                  f"{self.t_stop:.2f})"
                  f" - 3 x {self.sigma:g} = {self.F_abort_max:.3f} N, "
                  f"abort_ratio <= {self.ratio_max:.3f} "
                  f"(each rate with its own speed's t_stop: <= {self.ratio_max_per_row:.3f})"]
        return "\n".join(lines)


def max_tension_rate(t: np.ndarray, tension: np.ndarray) -> float:
    """Largest rate of rise [N/s] of the largest link tension over a run (steps x links)."""
    f = np.max(tension, axis=1)
    dt = np.diff(t)
    ok = dt > 0
    if not ok.any():
        return 0.0
    return float(max(np.max(np.diff(f)[ok] / dt[ok]), 0.0))


def tension_rates(params: CellParams, movements: Sequence[int] = (1, 2, 3, 4),
                  speed_factors: Sequence[float] = (1.0, 2.0, 5.0)) -> tuple[RateRow, ...]:
    """Run each movement at each speed factor; the rows of :class:`AbortBudget`."""
    mv = params.movement
    rows = []
    for number in movements:
        for f in speed_factors:
            speed = mv.speed * f
            p = replace(params, movement=replace(mv, number=int(number), speed=speed))
            result = run_movement(p)
            limits = MotionLimits(max(speed, mv.retract_speed), mv.accel, mv.jerk)
            rows.append(RateRow(int(number), float(f), speed, float(result.F_max),
                                max_tension_rate(result.t, result.tension),
                                stopping_time(limits.v_max, limits)))
    return tuple(rows)


def auto_stop_time(cell: CellParams) -> float:
    """Jerk-limited stopping time [s] from the faster of the cell's tool speeds."""
    mv = cell.movement
    v = max(mv.speed, mv.retract_speed)
    return stopping_time(v, MotionLimits(v, mv.accel, mv.jerk))


def abort_horizon(cell: CellParams, detect_time: float, stop_time: float) -> float:
    """t_detect + t_stop [s]; ``stop_time`` 0 means the cell's :func:`auto_stop_time`."""
    return detect_time + (stop_time if stop_time > 0 else auto_stop_time(cell))


def configured_speed_threshold(cell: CellParams, horizon: float,
                               sigma: float) -> tuple[float, float, tuple[RateRow, ...]]:
    """Lesson 4's abort threshold at the cell's configured speed (the monitor's default).

    F_abort [N] = F_break - r * horizon - 3 sigma, with r [N/s] the largest tension
    rate of movements 1-4 run by the core at ``movement.speed``, ``horizon`` [s] =
    t_detect + t_stop and ``sigma`` [N] the tension noise. Returns (F_abort, r, rows).
    """
    rows = tension_rates(cell, speed_factors=(1.0,))
    r = max(row.r for row in rows)
    return cell.material.F_break - r * horizon - 3.0 * sigma, r, rows


@dataclass(frozen=True)
class AbortRatio:
    """The monitor's abort threshold as a share of F_break, and how it was chosen."""

    ratio: float                  # F_abort / F_break [-]
    budget: dict | None           # principle 4's figures (r [N/s], horizon [s], sigma [N])
    note: str                     # what to tell the user ("" for a configured abort_ratio)


def monitor_abort_ratio(cell: CellParams, abort_ratio: float, horizon: float,
                        noise_sigma: float) -> AbortRatio:
    """Safety principle 4 at the cell's configured speed (:func:`configured_speed_threshold`,
    core runs of movements 1-4) over ``horizon`` [s] = t_detect + t_stop with tension noise
    ``noise_sigma`` [N]: with ``abort_ratio`` 0 its bound is the ratio; a set ``abort_ratio``
    [-] is taken when it does not exceed that bound and refused when it does (a threshold at
    F_break leaves no time to stop: abort_ratio 1.0 tore the sheet in every attack run).
    Raises ParameterError naming abort_ratio when the core cannot run, no threshold meets
    the principle, or a set ratio exceeds it."""
    what = f"abort_ratio {abort_ratio:g}"
    try:
        F_abort, r, rows = configured_speed_threshold(cell, horizon, noise_sigma)
    except (RuntimeError, ValueError) as exc:
        raise ParameterError(f"{what}: the core could not compute the tension rates "
                             f"({exc})") from None
    Fb = cell.material.F_break
    if abort_ratio > 0:
        if abort_ratio > F_abort / Fb:            # (the ratio as the bound states it)
            raise ParameterError(
                f"parameter 'abort_ratio' = {abort_ratio:g} is invalid: expected at most "
                f"{F_abort / Fb:.4f}, safety principle 4 at movement.speed "
                f"{cell.movement.speed:g} m/s (F_abort = {Fb:g} - {r:.3f} x {horizon:.3f} - "
                f"3 x {noise_sigma:g} = {F_abort:.4f} N); 0 takes that bound")
        return AbortRatio(abort_ratio, None, "")
    if F_abort <= 0:
        raise ParameterError(
            f"abort_ratio 0: no threshold meets safety principle 4 at movement.speed "
            f"{cell.movement.speed:g} m/s (r = {r:.3f} N/s, detect_time + stop_time = "
            f"{horizon:.3f} s): lower the speed or set abort_ratio")
    ratio = F_abort / Fb
    return AbortRatio(ratio, {"r": r, "horizon": horizon, "sigma": noise_sigma,
                              "rows": [(row.movement, row.F_max, row.r) for row in rows]},
                      f"abort_ratio 0: safety principle 4 at {cell.movement.speed * 1e3:g} mm/s: "
                      f"r = {r:.3f} N/s (movements 1-4, core), F_abort = {Fb:g} - {r:.3f} x "
                      f"{horizon:.3f} - 3 x {noise_sigma:g} = {F_abort:.4f} N, ratio {ratio:.3f}")


def abort_budget(params: CellParams | None = None, t_detect: float = DEFAULT_T_DETECT,
                 sigma: float = DEFAULT_SIGMA, movements: Sequence[int] = (1, 2, 3, 4),
                 speed_factors: Sequence[float] = (1.0, 2.0, 5.0)) -> AbortBudget:
    """Lesson 4's bound on the abort threshold for ``params`` (default cell when None)."""
    params = CellParams() if params is None else params
    rows = tension_rates(params, movements, speed_factors)
    return AbortBudget(params.material.F_break, max(r.r for r in rows), float(t_detect),
                       max(r.t_stop for r in rows), float(sigma), rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rheo_shaping.safety.abort_budget",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--params", help="params YAML of the cell (default: the default cell)")
    parser.add_argument("--t-detect", type=float, default=DEFAULT_T_DETECT)
    parser.add_argument("--sigma", type=float, default=DEFAULT_SIGMA)
    parser.add_argument("--max-factor", type=float, default=5.0)
    args = parser.parse_args(argv)
    from ..params.config import load_cell
    params = load_cell(args.params) if args.params else CellParams()
    factors = sorted({1.0, 2.0, args.max_factor} - {f for f in (2.0,) if f > args.max_factor})
    budget = abort_budget(params, args.t_detect, args.sigma, speed_factors=factors)
    print(budget.table())
    return 0 if math.isfinite(budget.F_abort_max) else 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
