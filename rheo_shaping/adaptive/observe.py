"""What the closed loop sees of a run: one :class:`Sample` per observation time, and the
same observables predicted by a model run.

A sample holds what the cell measures at process time ``t`` [s]: the executed tool pose
(``/tool/pose``), the force of the sheet on the tool (``/tool/wrench``, x and z), the
largest tension in a link touching the tool (``/sheet/contact_tension``, optional) and the
residual gap Delta of the profile frame (``/sheet/profile``, paper Fig. 12 b, optional).
:func:`predict` gives the model's values of the same observables at the samples' times
from a :class:`~rheo_shaping.sheet.simulation.RunResult`.  No ROS here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..params.validators import check_positive
from ..sheet.metrics import contact_tension, residual_gap
from ..sheet.simulation import RunResult, Simulation

#: The observables of a sample, in the order of :func:`observation_matrix`'s columns.
OBSERVABLES = ("wrench_x", "wrench_z", "contact_tension", "gap")


@dataclass(frozen=True)
class Sample:
    """One observation of the run at process time ``t`` [s]: tool pose (x, z) [m], force of
    the sheet on the tool (x, z) [N], contact tension [N] and gap Delta [m] (None: not
    measured; NaN is a lying source, refused by the estimator)."""

    t: float
    tool: tuple[float, float]
    wrench: tuple[float, float]
    contact_tension: float | None = None
    gap: float | None = None

    def values(self) -> np.ndarray:
        """(4,) the observables of :data:`OBSERVABLES`, NaN where not measured."""
        ct = math.nan if self.contact_tension is None else float(self.contact_tension)
        gap = math.nan if self.gap is None else float(self.gap)
        return np.array([float(self.wrench[0]), float(self.wrench[1]), ct, gap])

    def bad_value(self) -> str:
        """Why this sample is no data (a non-finite number where one was measured), or ""."""
        for name, value in (("t", self.t), ("tool x", self.tool[0]), ("tool z", self.tool[1]),
                            ("wrench x", self.wrench[0]), ("wrench z", self.wrench[1]),
                            ("contact_tension", self.contact_tension), ("gap", self.gap)):
            if value is not None and not math.isfinite(float(value)):
                return f"{name} = {value!r} at t = {self.t!r} s: expected a finite number"
        return ""


@dataclass(frozen=True)
class NoiseModel:
    """1-sigma noise of each observable: force [N] (each wrench axis), contact tension [N],
    gap [m].  The estimator weighs residuals by them (the monitor's noise_sigma is the
    default for forces; the camera's 0.2 mm for the gap)."""

    force: float = 0.005
    tension: float = 0.005
    gap: float = 2e-4

    def __post_init__(self) -> None:
        for name, unit in (("force", "N"), ("tension", "N"), ("gap", "m")):
            check_positive(f"NoiseModel.{name} [{unit}]", getattr(self, name))

    def sigmas(self) -> np.ndarray:
        """(4,) sigma of each of :data:`OBSERVABLES`."""
        return np.array([self.force, self.force, self.tension, self.gap])


def observation_matrix(samples: Sequence[Sample]) -> tuple[np.ndarray, np.ndarray]:
    """Times (n,) [s] and observables (n, 4) (NaN where not measured) of ``samples``."""
    t = np.array([s.t for s in samples], dtype=float)
    y = np.array([s.values() for s in samples], dtype=float).reshape(-1, len(OBSERVABLES))
    return t, y


def sample_of(sim: Simulation, gap: bool = True, tension: bool = True) -> Sample:
    """The noise-free sample of a :class:`~rheo_shaping.sheet.simulation.Simulation`'s
    present state (what the simulator node publishes)."""
    st = sim.state
    f = sim.tool_force()
    return Sample(t=float(st.t), tool=(float(st.tool[0]), float(st.tool[1])),
                  wrench=(float(f[0]), float(f[1])),
                  contact_tension=float(sim.contact_tension()) if tension else None,
                  gap=float(sim.delta()) if gap else None)


def noisy(sample: Sample, noise: NoiseModel, rng: np.random.Generator) -> Sample:
    """``sample`` with Gaussian noise of ``noise`` on every measured observable."""
    e = rng.normal(size=4) * noise.sigmas()
    return Sample(t=sample.t, tool=sample.tool,
                  wrench=(sample.wrench[0] + e[0], sample.wrench[1] + e[1]),
                  contact_tension=None if sample.contact_tension is None
                  else sample.contact_tension + e[2],
                  gap=None if sample.gap is None else sample.gap + e[3])


def step_gaps(run: RunResult, steps: np.ndarray) -> np.ndarray:
    """Delta [m] of ``run`` at step indices ``steps`` (inf where no part of the sheet is
    low: :func:`~rheo_shaping.sheet.metrics.residual_gap`)."""
    thickness = run.params.sheet.thickness
    return np.array([residual_gap(run.nodes(int(k)), thickness) for k in steps], dtype=float)


def predict(run: RunResult, times: np.ndarray, need_gap: np.ndarray) -> np.ndarray:
    """The model's observables (n, 4) at ``times`` (n,) [s] from ``run``: wrench and contact
    tension linear between the run's steps; the gap at the nearest step, only where
    ``need_gap`` (n,) bool (NaN elsewhere: it is the dearest to compute)."""
    t = run.t
    out = np.full((times.size, len(OBSERVABLES)), np.nan)
    out[:, 0] = np.interp(times, t, run.tool_force[:, 0])
    out[:, 1] = np.interp(times, t, run.tool_force[:, 1])
    ct = np.array([contact_tension(run.tension[k], run.tool_contact[k]) for k in range(t.size)])
    out[:, 2] = np.interp(times, t, ct)
    if need_gap.any():
        tg = times[need_gap]
        k = np.clip(np.searchsorted(t, tg), 1, t.size - 1)
        k = np.where(np.abs(t[k - 1] - tg) <= np.abs(t[k] - tg), k - 1, k)
        out[need_gap, 3] = step_gaps(run, k)
    return out
