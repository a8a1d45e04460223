"""The shaping cell in one process: simulator, planner and monitor on one executor.

For users without ``ros2 launch`` (``rheo-shaping cell``): the three nodes are
the same classes the executables run, created in one rclpy context that reads
the params file (``--ros-args --params-file``); they talk over DDS exactly as
separate processes do.  The simulator is the clock (``real_time_factor``,
default 50x), planner and monitor run on ``use_sim_time``.  The run ends when
the planner has finished (``done``) or, after an abort, holds, and the
simulator has reached ``movement.process_time``; :func:`run_cell` returns the
process figures (F_max, SF, Delta) the simulator measured.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import rclpy
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter

from ..planning.states import AT_REST
from ..adaptive.schedule import cycle_end
from ..adaptive.streamed import PACED_COMMAND_TIMEOUT
from .monitor import MonitorNode
from .planner import PlannerNode
from .session import eta, ros_session
from .simulator import SimulatorNode
from .topics import CLOCK, CLOCK_REMAP, CLOCK_TOPICS

#: Simulated seconds per step of the runner's simulator (its step period is
#: this divided by the real-time factor).
SIM_STEP = 0.2
#: Wall time [s] the run's end waits for its latched last messages to be acknowledged (a
#: reliable subscriber that matched them; a busy machine lost the planner's `done`).
END_ACK_S = 2.0


@dataclass
class CellResult:
    """What one run of the cell gave (SI units)."""

    movement: int
    F_max: float
    F_max_link: int
    F_max_time: float
    SF: float
    delta: float
    F_break: float
    process_time: float
    aborted: bool
    abort_reason: str
    planner_state: str
    wall_time_s: float
    achieved_factor: float
    finished: bool
    d: float = math.nan
    extra: dict = field(default_factory=dict)

    def summary(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "extra"}


def run_cell(params_file: str | Path | None = None, *, movement: int | None = None,
             real_time_factor: float = 50.0, timeout: float = 300.0,
             progress: Callable[[str], None] | None = print, progress_period: float = 10.0,
             overrides: dict[str, Sequence[Parameter]] | None = None,
             log_level: str = "warn", namespace: str = "",
             clock_topic: str = CLOCK.name, adaptive: bool = False) -> CellResult:
    """Run the cell once; returns its figures (raises ParameterError for bad parameters).

    ``overrides`` maps a node name to extra parameters for it; ``adaptive`` turns the
    planner's closed loop on (its parameter ``adaptive``); ``log_level``
    (debug, info, warn, error) is the nodes' logging threshold; ``namespace``
    (e.g. ``/cell2``) moves every node, topic and service of the cell there (``-r
    __ns:=NS``); ``clock_topic`` is where the simulator's clock goes: the absolute
    ``/clock`` (default, where rviz2 and ``ros2 bag`` look) or ``clock``, the namespace's
    own (``-r /clock:=clock`` for all three nodes: several simulated cells on one domain).
    """
    if clock_topic not in CLOCK_TOPICS:
        raise ValueError(f"clock_topic = {clock_topic!r}: expected one of "
                         f"{', '.join(CLOCK_TOPICS)}")
    args = ["rheo_shaping_cell", "--ros-args"]
    if params_file is not None:
        args += ["--params-file", str(params_file)]
    if namespace.strip("/"):
        args += ["-r", f"__ns:=/{namespace.strip('/')}"]
    if clock_topic != CLOCK.name:
        args += [*CLOCK_REMAP]
    common = [] if movement is None else [Parameter("movement.number", value=int(movement))]
    extra = {k: list(v) for k, v in (overrides or {}).items()}
    paced: list[Parameter] = []
    if adaptive:                        # the planner's closed loop (docs/closed-loop.md),
        # paced: the simulated cell waits at each refresh's join for its re-plan
        extra["planner"] = [Parameter("adaptive", value=True),
                            Parameter("adaptive_pace", value=True), *extra.get("planner", ())]
        paced = [Parameter("command_timeout", value=PACED_COMMAND_TIMEOUT)]
    sim_params = [Parameter("real_time_factor", value=float(real_time_factor)),
                  Parameter("step_period", value=SIM_STEP / float(real_time_factor)),
                  Parameter("progress_period", value=0.0), *paced, *common,
                  *extra.get("simulator", ())]
    sim_time = [Parameter("use_sim_time", value=True)]
    with ros_session(args, EventsExecutor) as (context, executor, nodes):
        level = getattr(rclpy.logging.LoggingSeverity, log_level.upper())
        prefix = namespace.strip("/").replace("/", ".")
        for name in ("simulator", "planner", "monitor"):
            rclpy.logging.set_logger_level(f"{prefix}.{name}" if prefix else name, level)
        t_wall = time.monotonic()
        sim = SimulatorNode(context=context, parameter_overrides=sim_params, message_info=False)
        nodes.append(sim)
        # no /shaping/checked: the EventsExecutor passes no message info, and nothing can
        # stall between nodes that share this process
        monitor = MonitorNode(context=context, parameter_overrides=[
            *sim_time, Parameter("acknowledge", value=False),
            # one executor: the simulator steps only when the monitor can judge, so stale
            # data is judged on the cell's clock (a busy machine slows this cell)
            Parameter("stale_clock", value="cell"), *common,
            *extra.get("monitor", ())])
        nodes.append(monitor)
        planner = PlannerNode(context=context,
                              parameter_overrides=[*sim_time, *common, *extra.get("planner", ())])
        nodes.append(planner)
        for node in nodes:
            executor.add_node(node)
        cell = planner.cell_used
        pt = cell.movement.process_time
        next_report = 0.0
        say = progress or (lambda _msg: None)
        say(f"cell: movement {cell.movement.number}, process {pt:g} s, simulated time "
            f"x{real_time_factor:g}; abort at {monitor.threshold:.3f} N "
            f"({monitor.ratio:.3f} x F_break)")
        deadline = t_wall + timeout
        finished = False
        t_started = None
        while time.monotonic() < deadline and context.ok():
            executor.spin_once(timeout_sec=0.05)
            ran = planner.streamer.plan if planner.streamer is not None else None
            if adaptive and ran is not None:    # a re-planned cycle is judged at its end
                sim.run.end_at(cycle_end(pt, planner.plan.duration, ran.duration))
            if t_started is None and sim.started:
                t_started = time.monotonic()
            t = sim.process_time if sim.started else 0.0
            if (progress is not None and progress_period > 0 and t_started is not None
                    and sim.started and t >= next_report):
                st = sim.sim.state
                elapsed = time.monotonic() - t_started
                left = eta(elapsed, t, pt)
                say(f"  t = {t:6.1f} / {pt:g} s{left}  tool ({st.tool[0] * 1e3:6.2f}, "
                    f"{st.tool[1] * 1e3:6.2f}) mm  largest tension {max(st.tension):.4f} N  "
                    f"planner {planner.state}, monitor {monitor.state}")
                while next_report <= t:
                    next_report += progress_period
            if sim.summary is not None and planner.state in AT_REST:
                finished = True
                break
        wall = time.monotonic() - t_wall
        run_wall = time.monotonic() - (t_started if t_started is not None else t_wall)
        # the end's latched messages (the planner's last state, an abort) acknowledged by
        # the subscribers that asked for them before the process ends with its session
        # (after the run's times: the wait is not the run's)
        for pub in (planner.pub_state, monitor.pub_abort, sim.pub_abort):
            pub.wait_for_all_acked(Duration(seconds=END_ACK_S))
        s = sim.run.summary_so_far()      # timed out or aborted before the end: so far
        done = sim.summary is not None
        return CellResult(
            movement=cell.movement.number, F_max=s.F_max, F_max_link=s.F_max_link,
            F_max_time=s.F_max_time, SF=s.SF, delta=s.delta,
            F_break=cell.material.F_break,
            process_time=sim.run.cell.movement.process_time if done else sim.process_time,
            aborted=planner.aborted or monitor.state == "aborted",
            abort_reason=planner.abort_reason or monitor.abort_reason,
            planner_state=planner.state, wall_time_s=wall,
            achieved_factor=sim.process_time / run_wall if run_wall > 0 else math.nan,
            finished=finished, d=cell.movement.d if cell.movement.number == 4 else math.nan,
            extra={"run_time": sim.process_time, "lockstep_waits": sim.lockstep_waits,
                   "plan_duration": (planner.streamer.plan.duration
                                     if planner.streamer and planner.streamer.plan
                                     else math.nan),
                   "adaptive": list(planner.adaptive_log),
                   "abort_threshold": monitor.threshold,
                   "history": list(sim.history), **_stop_times(planner, sim)})


def _stop_times(planner: PlannerNode, sim: SimulatorNode) -> dict:
    """When the abort's stop started and reached rest, in process time [s] (None without)."""
    st = planner.streamer
    if st is None or st.abort_time is None or sim.process_offset_ns is None:
        return {"abort_time": None, "rest_time": None}
    offset = sim.process_offset_ns / 1e9
    rest = st.rest_time
    return {"abort_time": st.abort_time - offset,
            "rest_time": None if rest is None else rest - offset}
