"""Settings of the ROS 2 nodes (simulator, planner, monitor, gap_watch): one schema for
the nodes, the params YAML and the one-process runner (``rheo-shaping cell``).

Like :mod:`rheo_shaping.params.cell`, every field carries a
:class:`~rheo_shaping.params.schema.Spec`
(description, unit, range); ``rheo_shaping/nodes/ros_params.py`` turns them into
ROS parameters with descriptors and range checks.  The names are plain (no
section prefix): they live in the node's own section of the params file
(keyed ``/**/<node>`` so that it applies in any namespace)::

    /**/simulator:
      ros__parameters:
        real_time_factor: 20.0

No ROS imports here.  The defaults are explained in ``docs/ros.md``; the
monitor's ``abort_ratio`` is justified by safety principle 4 with the
numbers of :mod:`rheo_shaping.safety.abort_budget`.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from .gapwatch_params import GapWatchNodeParams
from .schema import iter_fields, param


def _max_clock_jump():
    """``max_clock_jump`` of the nodes on simulated time (planner, monitor)."""
    return param(
        5.0, "a /clock message more than this ahead of the previous one, or behind it, or "
        "negative, is refused and stops the run with the reason; must exceed the simulator's "
        "step", "s", 0.0, 3600.0, lo_open=True)


def _check_cell(what: str, then: str):
    """``check_cell`` of the planner and the monitor."""
    return param(
        True, f"{what} the simulator's cell: wait for its fingerprint on /shaping/cell; a cell "
        f"that differs from this node's is {then}, naming each parameter and both values")


@dataclass(frozen=True)
class SimulatorNodeParams:
    """The ``simulator`` node: how it steps the sheet and what it publishes."""

    real_time_factor: float = param(
        1.0, "simulated seconds per wall-clock second; other than 1 (or publish_clock) the "
        "simulator publishes /clock and the other nodes need use_sim_time:=true", "", 0.0, 1000.0,
        lo_open=True)
    step_period: float = param(
        0.02, "wall-clock period of the step timer; each step advances simulated time by "
        "real_time_factor x step_period (the core sub-steps within "
        "it)", "s", 0.0, 1.0, lo_open=True)
    publish_period: float = param(
        0.05, "simulated time between published sheet states (0: every step)", "s", 0.0, 10.0,
        tunable=True)
    publish_markers: bool = param(True, "publish /sheet/markers for RViz", tunable=True)
    marker_period: float = param(
        0.2, "wall-clock time between /sheet/markers", "s", 0.0, 60.0, lo_open=True, tunable=True)
    publish_clock: bool = param(
        False, "publish /clock (simulated time) even when real_time_factor is 1")
    batch_k1: float = param(
        1.0, "the batch this simulator plays: its k1 as a multiple of the params file's (a test "
        "of a cell whose material differs from its params file, as a real batch's does; the "
        "cell it announces stays the params file's)", "", 0.2, 5.0)
    batch_c2: float = param(
        1.0, "the batch this simulator plays: its c2 as a multiple of the params file's", "",
        0.2, 5.0)
    batch_mass: float = param(
        1.0, "the batch this simulator plays: its mass per length as a multiple of the params "
        "file's", "", 0.2, 5.0)
    batch_friction_mould: float = param(
        -1.0, "the batch this simulator plays: the sheet's Coulomb friction on the mould "
        "(-1: the params file's effects.friction_mould)", "", -1.0, 2.0)
    batch_friction_tool: float = param(
        -1.0, "the batch this simulator plays: the sheet's Coulomb friction on the tool (-1: "
        "the params file's effects.friction_tool)", "", -1.0, 2.0)
    lockstep: bool = param(
        True, "on simulated time: while set-points stream, step only when the set-point for the "
        "end of the step has arrived (waiting at most command_timeout); the run slows down "
        "rather than guessing the tool's motion")
    command_timeout: float = param(
        0.2, "wall-clock time after the newest /tool/command after which the stream counts as "
        "lost: the tool holds its last set-point and lockstep stops waiting (keep it below "
        "the monitor's max_data_age)", "s", 0.0, 10.0, lo_open=True)
    monitor_lead: int = param(
        1, "on simulated time: tension samples the simulator may publish beyond the newest one "
        "the monitor has acknowledged on /shaping/checked, so that a stalled link stalls the "
        "simulation, not the monitor's view of it (0: do not wait; without acknowledgements for "
        "command_timeout it does not wait either)", "", 0, 1000)
    start_on_command: bool = param(
        True, "hold the settled sheet at process time 0 until the first /tool/command; the "
        "process (and the tool, placed at that set-point) starts then, as in the offline run "
        "(with lockstep on simulated time, /clock holds too, so the plan starts where the "
        "simulation is); false: the process starts with the node")
    offered_deadline: float = param(
        0.1, "QoS deadline offered on /sheet/tensions and /sheet/contact_tension; a subscriber "
        "requesting a shorter one (the monitor requests max_data_age) gets no data", "s",
        0.0, 60.0, lo_open=True)
    diagnostics_period: float = param(
        1.0, "wall-clock time between the simulator's /diagnostics "
             "status", "s", 0.0, 60.0, lo_open=True, tunable=True)
    progress_period: float = param(
        10.0, "process time between progress lines in the log (0: none)", "s", 0.0, 3600.0,
        tunable=True)
    max_tool_speed: float = param(
        0.05, "joint limit of the executed tool path: a set-point path faster than this stops the "
        "tool (it holds) with the reason, published on /shaping/abort", "m/s", 0.0, 1.0,
        lo_open=True)
    max_tool_accel: float = param(
        1.0, "joint limit: a set-point path accelerating faster than this stops the tool",
        "m/s^2", 0.0, 100.0, lo_open=True)
    max_tool_jump: float = param(
        5e-3, "joint limit: a set-point farther than this from the one before (or from the tool, "
        "for the first) stops the tool", "m", 0.0, 1.0, lo_open=True)
    monitor_timeout: float = param(
        0.5, "once the monitor has acknowledged samples (/shaping/checked), no acknowledgement "
        "for this wall-clock time once a set-point came is a lost (frozen) monitor: the tool "
        "holds, the reason goes out on /shaping/abort (before the first set-point the tool "
        "stands still and nothing latches; on simulated time the sheet stands still meanwhile, "
        "at most monitor_lead samples past the newest acknowledgement; 0, never, tore the "
        "sheet with the monitor frozen)", "s", 0.0, 10.0, lo_open=True)
    camera: bool = param(
        True, "publish sheet/measured_profile: a simulated camera with the measurement model of "
        "rheo-shaping record (rheo_shaping.records.measurement: points along the centreline, "
        "noise, "
        "dropouts), stamped with the state's time")
    camera_rate: float = param(2.0, "camera frames per second of process time", "Hz", 0.0, 100.0,
                               lo_open=True)
    camera_spacing: float = param(3e-3, "spacing of the camera's points along the centreline",
                                  "m", 0.0, 0.1, lo_open=True)
    camera_noise: float = param(3e-4, "standard deviation of each camera point (x and z)", "m",
                                0.0, 0.01)
    camera_frame_dropout: float = param(0.05, "fraction of camera frames lost", "", 0.0, 0.9)
    camera_point_dropout: float = param(0.02, "fraction of points lost within a frame", "",
                                        0.0, 0.9)
    camera_seed: int = param(0, "seed of the camera's noise and dropouts (0: random)", "", 0,
                             2**31 - 1)
    cake_parent_frame: str = param(
        "world", "parent frame of the cell's frame cake on /tf_static (as tf2's static "
        "broadcaster sends it, once, latched): where the mould stands in a robot's TF tree; "
        "empty: no /tf_static")
    cake_xyz: tuple = param(
        [0.0, 0.0, 0.0], "position of frame cake's origin (the mould's wall at the workplane) "
        "in cake_parent_frame: x, y, z", "m", -1000.0, 1000.0, length=3)
    cake_rpy: tuple = param(
        [0.0, 0.0, 0.0], "orientation of frame cake in cake_parent_frame: roll, pitch, yaw "
        "about the parent's fixed x, y, z axes (static_transform_publisher's --roll --pitch "
        "--yaw)", "rad", -2 * math.pi, 2 * math.pi, length=3)

    def __post_init__(self) -> None:
        check_frame_id("cake_parent_frame", self.cake_parent_frame)


#: The cell's frame (docs/interfaces.md): every message of the cell is stamped in it.
CAKE_FRAME = "cake"


def check_frame_id(name: str, value: str) -> None:
    """A parent frame for ``cake`` as tf2 takes it ("" for none), or ValueError naming
    ``name``, the value and what was expected."""
    if value == "":
        return
    if (not re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_./-]*", value) or value == CAKE_FRAME
            or "//" in value or value.endswith("/")):
        raise ValueError(
            f"parameter '{name}' = {value!r} is invalid: expected a TF frame name other than "
            f"{CAKE_FRAME!r} (letters, digits, _ . - and / between names, no leading /: "
            f"tf2 refuses one), or '' for no /tf_static")


@dataclass(frozen=True)
class PlannerNodeParams:
    """The ``planner`` node: streaming, interlock, abort stop and retract, d optimisation."""

    control_rate: float = param(
        50.0, "rate of the /tool/command set-points on the node's clock (simulated time with "
        "use_sim_time)", "Hz", 1.0, 1000.0)
    autostart: bool = param(
        True, "start the plan as soon as the interlock allows (else wait for ~/start); never "
        "when /tool/pose shows the tool away from home and from the plan's start")
    start_tolerance: float = param(
        2e-3, "autostart only with the measured tool this close to tool.home or the plan's start",
        "m", 0.0, 1.0, lo_open=True)
    wait_for_monitor: bool = param(
        True, "interlock: move only while the monitor reports ready (/shaping/ready) with "
        "fresh data; a lost monitor stops the tool")
    monitor_timeout: float = param(
        1.0, "wall-clock age of the monitor's last ready heartbeat beyond which it counts as "
        "lost", "s", 0.0, 60.0, lo_open=True)
    max_lead: float = param(
        0.5, "the most the set-points may run ahead of the executed tool pose (/tool/pose stamp), "
        "on the node's clock, whatever /clock does; must exceed the simulator's step "
        "(real_time_factor x step_period), checked at the start", "s", 0.0, 10.0, lo_open=True)
    max_clock_jump: float = _max_clock_jump()
    check_cell: bool = _check_cell("run only on", "refused")
    retract_speed: float = param(
        1e-3, "tool speed of the slow retract to home after an "
              "abort", "m/s", 0.0, 0.1, lo_open=True)
    retract_accel: float = param(
        2.5e-3, "tool acceleration limit of the retract after an "
                "abort", "m/s^2", 0.0, 10.0, lo_open=True)
    retract_jerk: float = param(
        2.5e-2, "tool jerk limit of the retract after an "
                "abort", "m/s^3", 0.0, 1000.0, lo_open=True)
    clearance_factor: float = param(
        1.0, "refuse a plan whose tool comes closer to the cake or the workplane than "
        "clearance_factor x sheet.thickness: it would pinch the sheet, whose tension then jumps "
        "faster than any monitor can stop the tool (0: no check)", "", 0.0, 10.0)
    trajectory_period: float = param(
        0.1, "time between the points of /tool/planned_trajectory (every jerk switch is "
        "added)", "s", 0.0, 10.0, lo_open=True, tunable=True)
    optimise_d: bool = param(
        False, "movement 4: before moving, pick d with the core model (smallest predicted "
        "F_max with Delta <= delta_limit, paper Fig. 18)")
    d_min: float = param(0.010, "smallest d tried by optimise_d", "m", 0.0, 1.0)
    d_max: float = param(0.020, "largest d tried by optimise_d", "m", 0.0, 1.0)
    d_step: float = param(0.0005, "spacing of the d values tried by optimise_d",
                          "m", 0.0, 1.0, lo_open=True)
    delta_limit: float = param(
        5e-3, "quality limit on the residual gap Delta for "
              "optimise_d", "m", 0.0, 1.0, lo_open=True)
    optimise_workers: int = param(
        1, "processes used by optimise_d (1: in the node's process)", "", 1, 64)
    adaptive: bool = param(
        False, "closed loop: estimate the batch's k1, c2 and mass per length from /tool/wrench "
        "and /sheet/contact_tension during the run and re-plan the rest of the movement's "
        "stroke speed and dwells (docs/closed-loop.md); the monitor stays independent")
    adaptive_refresh: float = param(
        2.0, "process time between two estimates and re-plans of the closed loop (and one at "
        "each move's start and end)", "s", 0.5, 60.0)
    adaptive_join_lead: float = param(
        1.0, "a re-plan joins the running plan this much process time after the newest "
        "set-point sent when it began (its compute time must fit in it: else it is dropped, "
        "named in the log)", "s", 0.1, 30.0)
    adaptive_pace: bool = param(
        False, "closed loop on simulated time: while a refresh runs, stream no set-point "
        "beyond its join, so a simulated cell faster than real time waits for its loop (its "
        "simulator in lockstep, with a command_timeout longer than a refresh's wall time) "
        "instead of running past the join; ignored on wall time: a real tool cannot wait")


#: The largest ``abort_ratio`` any cell may set: a threshold at F_break leaves no time to stop
#: (a set ratio is further checked against principle 4 at the cell's speed).
MAX_ABORT_RATIO = 0.99

#: ``abort_ratio`` value meaning: compute it with safety principle 4 for the
#: cell's configured speed (rheo_shaping.safety.abort_budget; docs/ros.md "Abort threshold").
AUTO_ABORT_RATIO = 0.0


@dataclass(frozen=True)
class MonitorNodeParams:
    """The ``monitor`` node: thresholds, staleness, trend prediction."""

    abort_ratio: float = param(
        AUTO_ABORT_RATIO, "abort when a link tension reaches abort_ratio x material.F_break; 0: "
        "the largest ratio safety principle 4 allows at the cell's configured speed, "
        "(F_break - r (detect_time + stop_time) - 3 noise_sigma) / F_break with r the largest "
        "tension rate of movements 1-4 computed by the core at start; a ratio above that "
        "bound is refused at start", "", 0.0, MAX_ABORT_RATIO)
    noise_sigma: float = param(
        0.005, "1-sigma noise of the tension data budgeted by abort_ratio 0 (simulated data: "
        "none; a load cell's)", "N", 0.0, 10.0)
    max_tension_ratio: float = param(
        10.0, "a tension above max_tension_ratio x material.F_break (or below -3 noise_sigma) "
        "is not data but a lying source: abort", "", 1.0, 1e6)
    warn_ratio: float = param(
        0.8, "diagnostics WARN from this fraction of the abort "
             "threshold", "", 0.0, 1.0, lo_open=True, tunable=True)
    max_data_age: float = param(
        0.5, "longest time without tension data (wall-clock age of the newest sample on a "
        "steady clock, and the QoS deadline requested; with stale_clock 'auto' in a lockstep "
        "cell, the link tensions' on the cell's clock instead, the contact tension's on the "
        "wall only beyond 10 x max_data_age); longer: abort", "s", 0.0, 60.0, lo_open=True)
    stale_clock: str = param(
        "auto", "the clock max_data_age is judged on: 'auto', the cell's (simulated) clock when "
        "on simulated time and acknowledging (the simulator steps only on this monitor's "
        "acknowledgements: a starved machine slows the cell, it does not move the tool "
        "unwatched), else the wall's; 'cell': the cell's whenever on simulated time (the "
        "one-process cell: simulator and monitor share one executor, neither runs without the "
        "other); 'wall': always the wall's (a real cell)", choices=("auto", "cell", "wall"))
    max_stamp_age: float = param(
        2.0, "oldest header stamp accepted on /sheet/profile and /tool/wrench, against the "
        "node's clock (a source replaying old data); older: abort. On simulated time keep it "
        "well above the simulator's step", "s", 0.0, 3600.0, lo_open=True)
    period: float = param(
        0.05, "steady-clock period of the watchdog and of the /shaping/ready heartbeat", "s",
        0.0, 1.0, lo_open=True)
    diagnostics_period: float = param(
        0.5, "wall-clock time between /diagnostics messages", "s", 0.0, 60.0, lo_open=True,
        tunable=True)
    trend_abort: bool = param(
        False, "also abort when the tension's linear trend predicts the threshold within "
        "detect_time + stop_time (earlier aborts, more margin, but false aborts of runs that peak "
        "just below the threshold: docs/safety.md)")
    trend_window: float = param(
        1.0, "time span of the samples the tension trend is fitted to (node clock)", "s",
        0.0, 60.0, lo_open=True)
    trend_min_samples: int = param(4, "fewest samples for a trend", "", 2, 10000)
    detect_time: float = param(
        0.1, "t_detect: budgeted time from a tension to the planner's reaction (sample period, "
        "transport, monitor and planner)", "s", 0.0, 10.0)
    stop_time: float = param(
        0.0, "t_stop: the tool's stopping time; 0: computed from the cell's movement limits "
        "(jerk-limited stop from the faster of movement.speed and movement.retract_speed)", "s",
        0.0, 60.0)
    stamp_tolerance: float = param(
        0.05, "how far a header stamp may lie ahead of the node's clock before it is a fault "
        "(on simulated time: still ahead max_data_age of wall time after it arrived, so a /clock "
        "handled late is not a fault)", "s", 0.0, 10.0)
    startup_timeout: float = param(
        60.0, "wall-clock time after start within which tension data must arrive; none by "
        "then: abort", "s", 0.0, 3600.0, lo_open=True)
    abort_hold: float = param(
        1.0, "after an abort, the longest wall-clock time the acknowledgements on "
        "/shaping/checked wait for /shaping/planner_state to show the planner off its plan (a "
        "simulator faster than real time stands still meanwhile)", "s", 0.0, 60.0)
    max_clock_jump: float = _max_clock_jump()
    check_cell: bool = _check_cell("ready only on", "an abort")
    acknowledge: bool = param(
        True, "publish /shaping/checked, the DDS sequence number of each /sheet/tensions sample "
        "judged, which holds a simulator on simulated time to the monitor (monitor_lead); needs "
        "an executor that passes message info (not rclpy's experimental EventsExecutor, which "
        "the one-process cell uses: its nodes share a process, no link can stall between them)")


NODE_PARAMS = {"simulator": SimulatorNodeParams, "planner": PlannerNodeParams,
               "monitor": MonitorNodeParams, "gap_watch": GapWatchNodeParams}

#: Every node setting's name (what may sit beside the cell sections in a params file).
NODE_PARAMETER_NAMES: frozenset[str] = frozenset(
    fi.name for cls in NODE_PARAMS.values() for fi in iter_fields(cls))

#: Parameters every rclpy node has, which may appear in a params file.
ROS_BUILTIN_PARAMETERS: frozenset[str] = frozenset(
    {"use_sim_time", "start_type_description_service"})


def parameter_table(cls: type) -> str:
    """Markdown table of a parameter dataclass: name, default, unit, range, description."""
    rows = ["| parameter | default | unit | valid | at runtime | description |",
            "|---|---|---|---|---|---|"]
    for fi in iter_fields(cls):
        spec = fi.spec
        default = list(fi.default) if isinstance(fi.default, tuple) else fi.default
        if isinstance(default, bool):
            default = str(default).lower()
        valid = "" if fi.kind is bool or (fi.kind is str and not spec.choices) \
            else spec.range_text()
        if spec.unit and valid.endswith(f" {spec.unit}"):
            valid = valid[:-len(spec.unit) - 1]
        runtime = "tunable" if spec.tunable else "read-only"
        rows.append(f"| `{fi.name}` | {default} | {spec.unit} | {valid} | {runtime} | "
                    f"{spec.description} |")
    return "\n".join(rows)


if __name__ == "__main__":  # pragma: no cover
    for _name, _cls in NODE_PARAMS.items():
        print(f"### `{_name}`\n\n{parameter_table(_cls)}\n")
