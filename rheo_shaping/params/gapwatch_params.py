"""Settings of the ``gap_watch`` node and its core (rheo_shaping.gapwatch): the model
beside the cell, its residuals and states, the diagnosis on a sustained WARN.  One schema
with the other nodes (:mod:`rheo_shaping.params.node_params`, ``docs/ros.md``).  No ROS
imports here.
"""
from __future__ import annotations

from dataclasses import dataclass

from .schema import param


@dataclass(frozen=True)
class GapWatchNodeParams:
    """The ``gap_watch`` node (and its core, rheo_shaping.gapwatch.watch.GapWatch): the model
    beside the cell, the residuals, the states, the diagnosis on a sustained WARN."""

    model_file: str = param(
        "", "params file of the model cell to watch the cell with (a params file or a "
        "'rheo-shaping diagnose --write-scenario' output); empty: the node's own cell (/**)")
    floor_file: str = param(
        "", "JSON floor of the residuals (rheo_shaping.gapwatch.floor.ResidualFloor: largest "
        "residual in noise units of runs the model fits); empty: the one shipped in the package")
    wait_for_plan: bool = param(
        True, "the process starts at the stamp of the planner's tool/planned_trajectory (a "
        "later plan starts a new run); false: at the first tool/pose (a replayed record)")
    window: float = param(
        10.0, "process time over which the windowed residuals are taken", "s", 0.0, 600.0,
        lo_open=True)
    sustain: float = param(
        5.0, "process time the residual must stay above the floor (or the ERROR share) before "
        "the state says WARN (ERROR)", "s", 0.0, 600.0)
    error_share: float = param(
        0.1, "ERROR when the gap changes the process figures by more than this share: the tool "
        "force's systematic residual over the window against the model's peak tool force (a "
        "proxy of F_max), or the measured Delta against the model's", "", 0.0, 10.0,
        lo_open=True)
    min_profile_noise: float = param(
        5e-5, "smallest profile noise the online estimate may return (a camera's points are "
        "never exact; a noise-free simulated stream would make any residual huge in noise "
        "units)", "m", 0.0, 0.01, lo_open=True)
    min_force_noise: float = param(
        5e-3, "smallest tool force noise the online estimate may return: a load cell's (as the "
        "monitor's noise_sigma); the simulator's wrench is noise-free, and its finer steps "
        "than the watch's model part from it by about 4 mN RMS at x10", "N", 0.0, 10.0,
        lo_open=True)
    max_points: int = param(
        5000, "a camera frame with more points than this (or fewer than 3) is refused as "
        "malformed", "", 3, 1000000)
    max_stamp_jump: float = param(
        10.0, "a sample stamped more than this after the newest tool pose (or before the "
        "process start) is refused: the model would step through time no pose covers; a pose "
        "stream that goes on from there (10 poses) is taken up again, the gap bridged "
        "linearly, and after a gap of more than 3 max_stamp_jump the run is no longer "
        "judged", "s", 0.0, 3600.0, lo_open=True)
    max_record: float = param(
        1800.0, "process time kept for the record a diagnosis reads (from the process start: "
        "the model's state depends on the whole history)", "s", 1.0, 86400.0)
    max_lag: float = param(
        2.0, "wall-clock time a received sample may wait for the model; older ones are "
        "dropped (and counted on /diagnostics) so the watch never falls behind the "
        "cell", "s", 0.0, 60.0, lo_open=True)
    queue_limit: int = param(
        20000, "received samples waiting for the model beyond which the oldest are dropped",
        "", 10, 10000000)
    publish_period: float = param(
        0.5, "wall-clock time between residual, /diagnostics and marker messages", "s", 0.0,
        60.0, lo_open=True, tunable=True)
    diagnose_on_warn: bool = param(
        True, "on the first sustained WARN of a run, write the run so far as a record and "
        "diagnose it in a worker process; once a run that warned has ended, diagnose the "
        "whole run again")
    diagnosis_baseline: str = param(
        "held", "the diagnosis's sheet knobs: held as the model cell writes them (the model is "
        "the cell as commissioned, and the question is what changed since, as WARN asks) or "
        "calibrated within their tolerances ('rheo-shaping diagnose --baseline')",
        choices=("held", "calibrated"))
    report_dir: str = param(
        "", "directory for the records and diagnosis reports (empty: "
        "$TMPDIR/rheo_shaping_gapwatch)")
