"""What the tool follows in a closed-loop run: the movement's moves (paper Sec. 5, the
params file's scenario), a choice of stroke speed and dwell length, and the one plan from
t = 0 they make, re-joined at each re-plan.  No ROS here.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from ..params.cell import CellParams
from ..params.validators import check_finite, check_positive
from ..planning.plans import Plan, Waypoint
from ..planning.scenarios import FORCED, Move, movement_limits, movement_scenario
from .join import ToolState, plan_from_state, splice


@dataclass(frozen=True)
class Choice:
    """The rest of a movement: path speed of the forced strokes [m/s] and the dwells as a
    multiple of the params file's [-] (retracts scale with the speed, never below the
    params file's retract speed)."""

    speed: float
    dwell_factor: float = 1.0

    def __post_init__(self) -> None:
        check_positive("Choice.speed [m/s]", self.speed)
        check_finite("Choice.dwell_factor [-]", self.dwell_factor, non_negative=True)


@dataclass(frozen=True, eq=False)
class Schedule:
    """The plan from t = 0 the tool follows (``plan``), whose move of ``moves`` each of its
    segments belongs to (``owners``), the latest ``choice``, and ``settle`` [s]: the time
    after the plan's end until the gap is judged (the params file's process time minus its
    fixed plan's duration)."""

    cell: CellParams
    moves: tuple[Move, ...]
    plan: Plan
    owners: tuple[int, ...]
    choice: Choice
    settle: float

    @property
    def cycle_time(self) -> float:
        """s from the start until the gap is judged: the plan's end plus ``settle``."""
        return float(self.plan.duration + self.settle)

    def move_at(self, t: float) -> tuple[int, str, float]:
        """(move index, "move" or "dwell", time [s] already spent in that segment) at plan
        time ``t`` [s]; (len(moves), "done", 0) after the plan's end."""
        for seg, owner in zip(self.plan.segments, self.owners):
            if seg.t_start <= t < seg.t_end:
                return owner, seg.kind, t - seg.t_start
        return len(self.moves), "done", 0.0

    def dwell_spent(self, t: float, index: int) -> float:
        """Time [s] the tool has dwelt, up to ``t``, at the end of move ``index``."""
        pairs = zip(self.plan.segments, self.owners)
        return float(sum(min(t, s.t_end) - s.t_start for s, o in pairs
                         if o == index and s.kind == "dwell" and s.t_start < t))

    def rejoin(self, t_join: float, choice: Choice) -> "Schedule | None":
        """This schedule with the rest of the movement after ``t_join`` [s] under
        ``choice``, joined without a jump (:func:`.join.splice`); None once the forced
        strokes are over (retracts and settle are left as they are)."""
        index, kind, _ = self.move_at(t_join)
        if index >= len(self.moves) or not self.moves[index].label.startswith(FORCED):
            return None
        state = ToolState.of(self.plan, t_join)
        move = self.moves[index]
        rest = [as_waypoint(self.cell, m, choice) for m in self.moves[index + 1:]]
        limits = movement_limits(self.cell, choice.speed)
        if kind == "move":
            first: Waypoint | None = as_waypoint(self.cell, move, choice)
            dwell = 0.0
        else:
            first = None
            dwell = max(move.dwell * choice.dwell_factor - self.dwell_spent(t_join, index), 0.0)
            state = replace(state, velocity=(0.0, 0.0), acceleration=(0.0, 0.0))
        new, owners = plan_from_state(state, first, rest, limits, dwell, move.label)
        full = splice(self.plan, t_join, new)
        kept = sum(1 for s in self.plan.segments if s.t_start < t_join)
        return replace(self, plan=full, choice=choice,
                       owners=self.owners[:kept] + tuple(index + o for o in owners))


def move_speed(cell: CellParams, move: Move, choice: Choice) -> float:
    """Path speed [m/s] of ``move`` under ``choice``: the choice's for a forced stroke; a
    retract's scaled as the strokes are, never below the params file's retract speed."""
    mv = cell.movement
    if move.label.startswith(FORCED):
        return choice.speed
    return max(mv.retract_speed, mv.retract_speed * choice.speed / mv.speed)


def as_waypoint(cell: CellParams, move: Move, choice: Choice,
                dwell: float | None = None) -> Waypoint:
    """``move`` as a waypoint under ``choice`` (its dwell scaled unless ``dwell`` [s])."""
    dw = move.dwell * choice.dwell_factor if dwell is None else dwell
    return Waypoint(float(move.target[0]), float(move.target[1]), max(dw, 0.0), move.label,
                    movement_limits(cell, move_speed(cell, move, choice)))


def cycle_end(process_time: float, nominal_duration: float, plan_duration: float) -> float:
    """Process time [s] at which a run of a ``plan_duration`` [s] plan is judged: the plan's
    end plus the settle the params file leaves after its nominal plan (``process_time`` -
    ``nominal_duration``), never before ``process_time`` (:attr:`Schedule.cycle_time`)."""
    return max(process_time, plan_duration + max(process_time - nominal_duration, 0.0))


def fixed_schedule(cell: CellParams, choice: Choice | None = None) -> Schedule:
    """The params file's movement as a :class:`Schedule` (its plan equals
    :func:`~rheo_shaping.planning.movement.movement_plan`'s for the default ``choice``)."""
    from ..planning.movement import movement_plan
    sc = movement_scenario(cell)
    choice = Choice(cell.movement.speed) if choice is None else choice
    waypoints = [as_waypoint(cell, m, choice) for m in sc.moves]
    start = ToolState((float(sc.start[0]), float(sc.start[1])), (0.0, 0.0), (0.0, 0.0))
    plan, owners = plan_from_state(start, None, waypoints, movement_limits(cell, choice.speed))
    nominal = float(movement_plan(cell).duration)
    return Schedule(cell=cell, moves=sc.moves, plan=plan, owners=tuple(o - 1 for o in owners),
                    choice=choice, settle=max(cell.movement.process_time - nominal, 0.0))
