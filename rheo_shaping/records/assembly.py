"""A record assembled from what a recorder received of a running cell (``record-cell``): the
samples from the process start on, t = 0 at the start, the state at rest before it kept when
the first sample after the start is late (the recorder node's decisions, tested without ROS).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Collection

import numpy as np

from ..params.cell import CellParams
from ..units import NS
from .record import Record

#: How close [m] the last tool pose before the start must be to the first set-point for
#: the cell to count as at rest there.
REST_TOLERANCE = 1e-4


class RecordCellError(RuntimeError):
    """The cell could not be recorded; the message says why and what to do."""


@dataclass
class CellBuffer:
    """What ``record-cell`` has received of one cell (stamps on the cell's clock [ns])."""

    pose: list = field(default_factory=list)       # (stamp ns, x, z)
    profile: list = field(default_factory=list)    # (stamp ns, (M, 2) array)
    wrench: list = field(default_factory=list)     # (stamp ns, fx, fz)
    start_ns: int | None = None                    # the process start
    start_xz: tuple[float, float] | None = None    # the first set-point [m]
    first_rx_ns: int | None = None                 # stamp of the first state message received
    planner_state: str = ""
    ran: bool = False

    def command(self, t_ns: int, xz: tuple[float, float]) -> None:
        """A set-point: the earliest one stamped > 0 is the process start, its position
        the first set-point's."""
        if t_ns > 0 and (self.start_ns is None or t_ns <= self.start_ns):
            self.start_ns, self.start_xz = t_ns, xz

    def plan(self, t_ns: int) -> None:
        """A plan stamped ``t_ns`` (its start): an earlier process start than any seen."""
        if t_ns > 0 and (self.start_ns is None or t_ns < self.start_ns):
            self.start_ns = t_ns

    def state(self, state: str, moving: Collection[str]) -> None:
        """The planner's state: the run counts as run once it was one of ``moving`` (the
        planner's vocabulary, planning.states.MOVING)."""
        self.planner_state = state
        self.ran = self.ran or state in moving

    def recorded_time(self) -> float:
        """Process time [s] of the newest pose (0 before the start)."""
        if self.start_ns is None or not self.pose:
            return 0.0
        return max((self.pose[-1][0] - self.start_ns) / NS, 0.0)

    def complete(self, end_time: float, fixed_duration: bool,
                 at_rest: Collection[str]) -> bool:
        """Whether the recording is complete at process time ``end_time`` [s]: for a fixed
        duration once it is recorded, else also once the planner has run and come to rest
        (one of ``at_rest``: planning.states.AT_REST)."""
        return self.recorded_time() >= end_time and (
            fixed_duration or (self.planner_state in at_rest and self.ran))


def assemble(buf: CellBuffer, scenario: CellParams, name: str) -> Record:
    """The record of ``buf`` from the process start on (t = 0 at the start), for cell
    ``scenario``; :class:`RecordCellError` says why there is none."""
    b = buf
    if b.start_ns is None:
        raise RecordCellError("the process never started: no tool/command and no "
                              "tool/planned_trajectory seen (is the planner running?)")
    # Keep what the cell published from the start on.  The cell is at rest until the
    # first set-point (the simulator holds the settled sheet at process time 0), so the
    # last sample before the start is the state at the start: it is kept, stamped with
    # the start, when it is older than the first sample after it (a busy cell may
    # publish its first state after the start late) and its tool pose is the first
    # set-point's.
    t0 = b.start_ns
    pre_pose = [p for p in b.pose if p[0] < t0]
    pose = sorted(p for p in b.pose if p[0] >= t0)
    at_rest = bool(pre_pose) and (b.start_xz is None or math.hypot(
        pre_pose[-1][1] - b.start_xz[0], pre_pose[-1][2] - b.start_xz[1]) <= REST_TOLERANCE)
    if not pre_pose and (not pose or pose[0][0] - t0 > NS // 2):
        raise RecordCellError(
            f"no tool/pose before the process start and none at it (the first is "
            f"{(pose[0][0] - t0) / NS if pose else math.nan:.2f} s after it): record-cell "
            f"joined after the process had started; start it before the cell's planner "
            f"moves")

    def with_start(samples: list, always: bool) -> list:
        """Samples from t0 on; the last one before t0 re-stamped at t0 when the first
        after it is late (``always``: later than t0 at all, as the record's t = 0 is
        its first pose; else: more than the topic's median spacing)."""
        before = [x for x in samples if x[0] < t0]
        after = sorted((x for x in samples if x[0] >= t0), key=lambda x: x[0])
        stamps = sorted(x[0] for x in samples)
        spacing = float(np.median(np.diff(stamps))) if len(stamps) > 2 else 0.0
        late = not after or after[0][0] - t0 > (0 if always else spacing)
        if at_rest and before and late:
            return [(t0, *before[-1][1:])] + after
        return after

    if pose and pose[0][0] > t0 and not at_rest:
        raise RecordCellError(
            f"the first tool/pose after the process start is {(pose[0][0] - t0) / NS:.2f} s "
            f"late and the tool was not at rest at the first set-point before it")
    pose = with_start(b.pose, True)
    if len(pose) < 2:
        raise RecordCellError(f"fewer than two tool/pose messages after the process start "
                              f"({len(pose)})")
    frames = with_start(b.profile, False)
    if len(frames) < 2:
        raise RecordCellError(
            f"{len(frames)} sheet/measured_profile frame(s) after the process start: a "
            f"record needs a camera (the simulator's: camera:=true)")
    wrench = with_start(b.wrench, True)
    pose_a = np.array(pose, float)
    rec = Record(scenario=scenario, pose_t=(pose_a[:, 0] - t0) / NS, pose_xz=pose_a[:, 1:],
                 profile_t=np.array([(f[0] - t0) / NS for f in frames]),
                 profiles=tuple(f[1] for f in frames), name=name)
    if len(wrench) >= 2:
        w = np.array(wrench, float)
        rec = Record(**{**rec.__dict__, "wrench_t": (w[:, 0] - t0) / NS,
                        "wrench_xz": w[:, 1:]})
    return rec
