"""Seeded synthetic material tests from known constants (for planning and testing).

Nothing here is measured data: every curve is made from a model
(:mod:`rheo_shaping.material.response`, exact for these inputs) plus noise, and its
``source`` says so.  Use it to check that a planned test campaign (speeds,
number of specimens, creep tests) determines the constants you need before
running it.

A synthetic tensile test: ``t_rest`` seconds of the load cell at rest (the
samples at ``t <= 0``; ``t_rest = 0`` gives none, not even ``t = 0``), then a
pull at constant speed from ``t = 0``; at the first sample where the model force reaches
``F_break`` (crack initiation; the paper's average is 1.04 N) the force falls
linearly to zero over ``t_propagation`` seconds (crack propagation, about
10 s in the paper's Fig. 9) and stays there for ``t_after`` seconds.  Noise:
Gaussian, standard deviation ``noise_rel * |F| + noise_abs``; a load-cell
``offset`` [N] is added to every sample.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..material.burgers import Burgers
from ..material.three_element import ThreeElement
from ..params.validators import check_non_negative, check_positive
from .material_data import CreepCurve, CreepResiduals, TensileCurve
from ..material.response import elongation_response, force_response


@dataclass(frozen=True)
class SyntheticTensile:
    """A synthetic tensile curve and the truth behind it.

    ``offset`` [N] added to all samples; ``t_break`` [s] and ``F_break`` [N]
    where the crack starts (``None`` if the pull never reached it).
    """

    curve: TensileCurve
    offset: float
    t_break: float | None
    F_break: float | None
    true_force: np.ndarray


def synthetic_tensile_curve(material: "ThreeElement | "
                                      "Burgers", speed: float = 1e-3, *, seed: int = 0,
                            rate_hz: float = 10.0, t_rest: float = 5.0, F_break: float = 1.04,
                            break_spread: float = 0.0, t_propagation: float = 10.0,
                            t_after: float = 5.0,
                            t_max: float = 120.0, noise_rel: float = 0.01, noise_abs: float = 1e-3,
                            offset: float | None = None,
                            offset_sd: float = 0.02) -> SyntheticTensile:
    """One synthetic tensile test (see the module doc); ``offset=None`` draws it (sd ``offset_sd``
    [N])."""
    check_positive("speed [m/s]", speed)
    check_positive("rate_hz [1/s]", rate_hz)
    check_non_negative("t_rest [s]", t_rest)
    check_positive("F_break [N]", F_break, allow_inf=True)
    check_positive("t_propagation [s]", t_propagation)
    check_positive("t_max [s]", t_max)
    check_non_negative("noise_rel [-]", noise_rel)
    check_non_negative("noise_abs [N]", noise_abs)
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    n_rest = int(round(t_rest * rate_hz))
    t_pull = np.arange(0, int(round(t_max * rate_hz)) + 1) * dt
    F_pull = elongation_response(material, t_pull, speed * t_pull).force
    F_b = F_break * (1.0 + break_spread * rng.standard_normal()
                     ) if np.isfinite(F_break) else np.inf
    hit = np.flatnonzero(F_pull >= F_b)
    if hit.size:
        i_b = int(hit[0])
        t_b = float(t_pull[i_b])
        n_end = i_b + int(round((t_propagation + t_after) * rate_hz))
        t_pull = np.arange(0, n_end + 1) * dt
        F_pull = np.concatenate([F_pull[: i_b + 1], np.zeros(n_end - i_b)])
        after = t_pull > t_b
        F_pull[after] = F_pull[i_b] * \
            np.clip(1.0 - (t_pull[after] - t_b) / t_propagation, 0.0, None)
        F_crack: float | None = float(F_pull[i_b])
    else:
        t_b, F_crack = None, None
    if n_rest == 0:                      # no sample at rest at all, not even t = 0
        t_pull, F_pull = t_pull[1:], F_pull[1:]
    t = np.concatenate([(np.arange(-n_rest, 0)) * dt, t_pull])
    F_true = np.concatenate([np.zeros(n_rest), F_pull])
    off = float(rng.normal(0.0, offset_sd)) if offset is None else float(offset)
    noise = rng.standard_normal(t.size) * (noise_rel * np.abs(F_true) + noise_abs)
    curve = TensileCurve(t, F_true + off + noise, float(speed), material.length,
                         source=f"synthetic (seed {seed}) from {material!r}")
    return SyntheticTensile(curve, off, t_b, F_crack, F_true)


def synthetic_tensile_set(material: "ThreeElement | Burgers", speeds=(1e-3,), n_per_speed: int = 5,
                          seed: int = 0, **kw) -> list[SyntheticTensile]:
    """``n_per_speed`` synthetic tensile curves at each of ``speeds`` [m/s], seeds ``seed, seed+1,
    ...``."""
    out = []
    for i, v in enumerate(np.repeat(np.asarray(speeds, dtype=float), n_per_speed)):
        out.append(synthetic_tensile_curve(material, float(v), seed=seed + i, **kw))
    return out


def synthetic_creep_residuals(material: "ThreeElement | "
                                        "Burgers", force: float = 0.5, t1: float = 60.0,
                              n: int = 10, sd: float = 0.83e-3, seed: int = 0) -> CreepResiduals:
    """``n`` creep residuals F t1/c2 (Eq. 9) [m] plus Gaussian scatter ``sd`` [m] (Table 1's is
    0.83 mm)."""
    check_positive("force [N]", force)
    check_positive("t1 [s]", t1)
    check_non_negative("sd [m]", sd)
    rng = np.random.default_rng(seed)
    x = force * t1 / material.c2 + sd * rng.standard_normal(int(n))
    return CreepResiduals(np.full(n, force), np.full(n, t1), x, material.length,
                          source=f"synthetic (seed {seed}) from {material!r}")


def synthetic_creep_curve(material: "ThreeElement | Burgers", force: float = 0.5, t1: float = 60.0,
                          t_end: float = 120.0, rate_hz: float = 2.0, sd: float = 2e-4,
                          seed: int = 0) -> CreepCurve:
    """A creep-recovery curve: ``force`` [N] from 0 to ``t1`` [s], then 0; elongation noise ``sd``
    [m]."""
    check_positive("t_end [s]", t_end)
    rng = np.random.default_rng(seed)
    t = np.arange(0, int(round(t_end * rate_hz)) + 1) / rate_hz
    F = np.where(t < t1, force, 0.0)
    x = force_response(material, t, F, hold="step").elongation + sd * rng.standard_normal(t.size)
    return CreepCurve(t, F, x, material.length, "step", source=f"synthetic (seed {seed}) from "
                                                               f"{material!r}")
