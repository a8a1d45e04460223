"""Stand-ins for real runs: the simulator measured like a real cell measures it.

A real shaping cell reports the robot's tool pose (what it commands, at its
controller rate), a vision system's points on the sheet's centreline (its own
spacing, noise, frame rate and dropouts) and, optionally, a load cell's force
on the tool.  :func:`measure` gives that view of a run;
:func:`rheo_shaping.planning.movement.synthesize_record` runs the cell of a params set, with
whatever effects are switched on in ``params.effects``, and measures it that way.  The
:class:`~rheo_shaping.records.record.Record` carries the NOMINAL cell as its scenario (what
the user believes), never the truth.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sheet.effects import nominal
from ..params.cell import CellParams
from .record import Record
from ..params.schema import param
from ..sheet.simulation import RunResult


@dataclass(frozen=True)
class MeasurementParams:
    """How the cell's sensors see a run (defaults: a 2 Hz vision system, a robot at 50 Hz, a load
    cell)."""

    profile_rate: float = param(2.0, "vision frames per second", "Hz", 0.0, 1000.0, lo_open=True)
    profile_spacing: float = param(
        3e-3, "spacing of the vision points along the sheet's "
              "centreline", "m", 0.0, 0.1, lo_open=True)
    profile_noise: float = param(
        3e-4, "standard deviation of each vision point (x and z)", "m", 0.0, 0.01)
    frame_dropout: float = param(0.05, "fraction of vision frames lost", "", 0.0, 0.9)
    point_dropout: float = param(0.02, "fraction of points lost within a frame", "", 0.0, 0.9)
    pose_rate: float = param(
        50.0, "tool pose samples per second (the robot's "
              "report)", "Hz", 0.0, 10000.0, lo_open=True)
    pose_noise: float = param(
        5e-5, "standard deviation of the reported tool pose (x and z)", "m", 0.0, 0.01)
    wrench: bool = param(True, "record the load cell's force on the tool")
    wrench_rate: float = param(50.0, "load cell samples per second",
                               "Hz", 0.0, 10000.0, lo_open=True)
    wrench_noise: float = param(
        0.01, "standard deviation of the measured force (x and z)", "N", 0.0, 10.0)
    start_stamp: float = param(
        0.0, "stamp of the process start (e.g. 1.7e9); 0: the wall-clock time the record is "
        "written, as a real cell's stamps are (a zero stamp is a fault to the monitor)", "s",
        0.0, 1e10)


def resample_polyline(nodes: np.ndarray, spacing: float, phase: float) -> np.ndarray:
    """Points every ``spacing`` [m] of arc length along ``nodes`` (K, 2), the first at ``phase``
    [m]."""
    seg = np.hypot(*np.diff(nodes, axis=0).T)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    targets = np.arange(phase, s[-1], spacing)
    return np.c_[np.interp(targets, s, nodes[:, 0]), np.interp(targets, s, nodes[:, 1])]


def nodes_at(run: RunResult, t: float) -> np.ndarray:
    """The sheet's centreline (bond, masses, bond) at time ``t`` [s], linear between solver
    steps."""
    k = int(np.clip(np.searchsorted(run.t, t), 1, run.t.size - 1))
    t0, t1 = run.t[k - 1], run.t[k]
    w = 0.0 if t1 <= t0 else float(np.clip((t - t0) / (t1 - t0), 0.0, 1.0))
    return (1.0 - w) * run.nodes(k - 1) + w * run.nodes(k)


def profile_frame(nodes: np.ndarray, ms: MeasurementParams,
                  rng: np.random.Generator) -> np.ndarray:
    """One vision frame of the centreline ``nodes`` (K, 2) [m]: points every
    ``profile_spacing`` from a random phase, Gaussian noise, point dropout (frame
    dropout is the caller's).  Used by :func:`measure` and the simulator node's camera."""
    pts = resample_polyline(nodes, ms.profile_spacing, rng.uniform(0.0, ms.profile_spacing))
    pts = pts + rng.normal(0.0, ms.profile_noise, pts.shape)
    return pts[rng.random(len(pts)) >= ms.point_dropout]


def measure(run: RunResult, path, params: CellParams, measurement: MeasurementParams,
            rng: np.random.Generator, name: str = "") -> Record:
    """The sensors' view of ``run`` (tool commanded on ``path``)."""
    ms = measurement
    t_end = float(run.t[-1])
    pose_t = np.arange(0.0, t_end + 1e-9, 1.0 / ms.pose_rate)
    pose = np.array([path.position(t) for t in pose_t]) + \
        rng.normal(0.0, ms.pose_noise, (pose_t.size, 2))
    frame_t = np.arange(0.0, t_end + 1e-9, 1.0 / ms.profile_rate)
    frame_t = frame_t[rng.random(frame_t.size) >= ms.frame_dropout]
    profiles = []
    for t in frame_t:
        profiles.append(profile_frame(nodes_at(run, t), ms, rng))
    wrench_t = wrench = None
    if ms.wrench:
        wrench_t = np.arange(0.0, t_end + 1e-9, 1.0 / ms.wrench_rate)
        wrench = np.c_[np.interp(wrench_t, run.t, run.tool_force[:, 0]),
                       np.interp(wrench_t, run.t, run.tool_force[:, 1])]
        wrench = wrench + rng.normal(0.0, ms.wrench_noise, wrench.shape)
    return Record(scenario=nominal(params), pose_t=pose_t, pose_xz=pose, profile_t=frame_t,
                  profiles=tuple(profiles), wrench_t=wrench_t, wrench_xz=wrench, name=name)
