"""The model's own replay error: what a record of the model itself misfits when replayed.

The diagnosis drives its model with the record's measured tool pose, averaged
and reduced to knots (:func:`compare.tool_path`), on steps of its own.  With a
Maxwell link (c1 = 0) the force follows the tool's position, and the error
this makes (about 1 mN of tool force at the default pose noise, 0.003 in J) is
inside the stored effect-free null.  A Kelvin dashpot (c1 > 0) adds
``c2/(c1+c2) c1`` times the link's elongation rate to its force, so the
replay's tool speed matters: a speed from a noisy pose (50 um at 50 Hz) and a
smoothed stop misfit by several noise units (0.5 in J at c1 = 441 N s/m).  The
stored null holds no such case, so when a record's written cell has c1 > 0 the
diagnosis measures this error itself: the calibrated baseline is run on its
own planned path, sampled at the record's stamps with the record's pose noise
(and no other noise), replayed as a record, for ``DRAWS`` draws of the pose
noise.  The gap test's null is then the stored null plus this misfit
(every sum of a stored value and a draw, :func:`stats.gap_p_value`), and the
adequacy checks take their 95 % quantile from the same sums.  One simulation
per record and one per record and draw, only for a Kelvin cell.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from ..params.cell import CellParams
from ..planning.movement import movement_plan
from ..records.measurement import nodes_at, resample_polyline
from ..records.record import Record
from .compare import RecordData, noise_level
from .evaluate import Outcome, Task, all_ok
from .linear import Stack

#: Seed of the pose noise drawn for the model's own records (the same for every diagnosis).
SEED = 20261203
#: Draws of the pose noise: the gap test's null is the stored null plus each draw's misfit.
DRAWS = 8


def kelvin(params: CellParams) -> bool:
    """The cell's links carry a Kelvin dashpot (c1 > 0, material or effect)."""
    return params.material.c1 + params.effects.kelvin_c1 > 0.0


def pose_noise(record: Record) -> float:
    """Std [m] of the reported tool pose's white noise (x and z pooled; MAD of second
    differences, :func:`compare.noise_level`)."""
    s = [noise_level(record.pose_xz[:, k]) for k in (0, 1)]
    s = [v for v in s if np.isfinite(v)]
    return float(np.sqrt(np.mean(np.square(s)))) if s else 0.0


def own_record(record: Record, run, path, sigma_pose: float,
               rng: np.random.Generator) -> Record:
    """``run`` (the model on its planned ``path``) seen at ``record``'s stamps: the pose
    with white noise ``sigma_pose`` [m], the profiles and the force without noise."""
    pose = np.array([path.position(t) for t in record.pose_t])
    pose = pose + rng.normal(0.0, sigma_pose, pose.shape)
    spacing = _spacing(record)
    profiles = tuple(resample_polyline(nodes_at(run, t), spacing, 0.5 * spacing)
                     for t in record.profile_t)
    wrench = None
    if record.has_wrench:
        assert record.wrench_t is not None      # has_wrench: it has stamps
        wrench = np.c_[np.interp(record.wrench_t, run.t, run.tool_force[:, 0]),
                       np.interp(record.wrench_t, run.t, run.tool_force[:, 1])]
    return replace(record, pose_xz=pose, profiles=profiles, wrench_xz=wrench,
                   name=f"{record.name} (model)")


def _spacing(record: Record) -> float:
    """Median spacing [m] of the record's profile points (3 mm when it has none)."""
    gaps = [np.hypot(*np.diff(np.asarray(f, float).reshape(-1, 2), axis=0).T)
            for f in record.profiles if len(f) > 1]
    joined = np.concatenate(gaps) if gaps else np.zeros(0)
    return float(np.median(joined)) if joined.size else 3e-3


def replay_misfit(data: Sequence[RecordData], params: Sequence[CellParams],
                  run: Callable[[list[Task]], list[Outcome]], sp: float, sf: float,
                  draws: int = DRAWS) -> np.ndarray | None:
    """``J_replay`` (``draws``,): the balanced misfit (noise units, :mod:`stats`) of records
    made by the model ``params[i]`` itself on its planned path, at ``data[i]``'s stamps and
    pose noise, against their replay; one value per draw of the pose noise (the misfit
    depends on it: 0.43-0.58 over five draws at c1 = 441 N s/m).  None where a run fails.
    Costs one run per record and one per record and draw."""
    try:
        plans = [movement_plan(p) for p in params]
    except (ValueError, RuntimeError):      # no plan for the baseline: no allowance either
        return None
    gen = run([Task(replace(d, path=path), p, keep_run=True)
               for d, p, path in zip(data, params, plans)])
    if not all_ok(gen):
        return None
    rng = np.random.default_rng(SEED)
    sigma = [pose_noise(d.record) for d in data]
    own = [[RecordData.of(own_record(d.record, o.run, path, s, rng))
            for d, o, path, s in zip(data, gen, plans, sigma)] for _ in range(draws)]
    outs = run([Task(d, p) for group in own for d, p in zip(group, params)])
    if not all_ok(outs):
        return None
    n = len(params)
    J = np.empty(draws)
    for k, group in enumerate(own):
        o = outs[k * n:(k + 1) * n]
        stack = Stack([d.point_frame for d in group], [d.record.has_wrench for d in group],
                      sp, sf)
        stack.set_force_count(o)
        z = stack.vec(o)
        J[k] = float(z @ z)
    return J
