"""A recorded run of a shaping cell, in memory (docs/interfaces.md, "Recorded runs").

This is what the diagnosis reads; :mod:`rheo_shaping.records.bag` reads and
writes it as a rosbag2 (MCAP) directory with ``scenario.yaml``, and imports
it from CSV tables.  Times are seconds from the process start (t = 0 at the
earliest ``/tool/pose`` stamp); positions are in frame ``cake`` [m].
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..params.cell import CellParams


@dataclass(frozen=True)
class Record:
    """One recorded run: measured tool pose, vision profiles, optional tool force."""

    scenario: CellParams                 # the nominal model of the cell (scenario.yaml)
    pose_t: np.ndarray                   # (K,) s, /tool/pose stamps
    pose_xz: np.ndarray                  # (K, 2) m, measured tool reference point
    profile_t: np.ndarray                # (F,) s, /sheet/measured_profile stamps
    profiles: tuple[np.ndarray, ...]     # F arrays (M_f, 2) m, centreline points top -> workplane
    wrench_t: np.ndarray | None = None   # (W,) s, /tool/wrench stamps
    wrench_xz: np.ndarray | None = None  # (W, 2) N, force of the sheet on the tool (x, z)
    name: str = ""                       # for reports (the directory's name)
    path: Path | None = field(default=None, compare=False)

    @property
    def duration(self) -> float:
        """Last stamp of any topic [s]."""
        ends = [self.pose_t[-1], self.profile_t[-1] if self.profile_t.size else 0.0]
        if self.wrench_t is not None and self.wrench_t.size:
            ends.append(self.wrench_t[-1])
        return float(max(ends))

    @property
    def has_wrench(self) -> bool:
        return self.wrench_t is not None and self.wrench_t.size > 0
