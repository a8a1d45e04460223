"""The misfit, its effective sample size and the tests the verdict rests on.

Balanced misfit.  J = (J_p + J_f) / 2 with J_p = mean(r_p^2) / s_p^2 over the
profile points and J_f = mean(|r_f|^2) / (2 s_f^2) over the tool-force
samples: each observable weighs one half whatever its sample count (a record
has ~3x more force samples than profile points).  J = 1: within noise.

Effective sample size.  Residuals are correlated along the sheet and in time;
each observable's n_eff is its count times (1 - rho) / (1 + rho) per
direction (AR(1)), rho the lag-1 autocorrelation of the baseline's residual:
along each frame and between consecutive frames' mean for the profile, in
time for each force axis.

Tests.

* Gap test: is there a gap the calibrated baseline cannot explain?  The
  baseline's excess misfit J - 1 is compared with its distribution on
  effect-free records from a model that differs from the diagnosis's in
  numerics (finer chain, smaller step, softer contact) and in the written
  scenario (values perturbed within tolerance): the conformal p-value
  (1 + #{null >= x}) / (n + 1) against the stored null sample.  A name needs
  p_gap <= ALPHA, which caps the false-name rate at ALPHA on records
  exchangeable with the calibration's, by construction.
* Effect test: likelihood ratio LR = sum_o n_eff_o ln(J_base,o / J_eff,o)
  against chi^2 with the effect's parameter count; p Bonferroni-corrected
  over the candidates tried.
* Adequacy: what the named effect leaves must look like the effect-free
  baseline (excess at most the null's 95 % quantile, fit and holdout), up to
  the model's own discretisation error at the effect (:mod:`check`).
"""
from __future__ import annotations

import json
import math
from contextlib import contextmanager
from contextvars import ContextVar
from functools import lru_cache
from pathlib import Path
from typing import Iterator

import numpy as np

ALPHA = 0.05
#: Excess misfit J - 1 of the calibrated baseline on effect-free records, fit and holdout
#: records: ``rheo_shaping/data/diagnosis_null.json``, measured by
#: ``benchmarks/diagnosis_null.py`` (200 effect-free cases of ``diagnose-benchmark`` with their
#: own seed: true chain 63 masses, half steps, softer contact; diagnosis N = 31; 70 s records;
#: the default measurement model).  Another cell, record length or sensor: measure it again.
NULL_FILE = Path(__file__).resolve().parent.parent / "data" / "diagnosis_null.json"


@lru_cache(maxsize=1)
def _null_sample() -> dict:
    data = json.loads(NULL_FILE.read_text())
    return {"fit": np.sort(np.asarray(data["fit"], float)),
            "holdout": np.sort(np.asarray(data["holdout"], float))}


#: The null sample the tests use in this context (None: the stored numerics null); a
#: diagnosis sets its model-form floor here (:mod:`.floor`, :func:`using_null`).
_ACTIVE: ContextVar[dict | None] = ContextVar("diagnosis_null", default=None)


@contextmanager
def using_null(sample: dict | None) -> Iterator[None]:
    """Within the block, the gap test and the adequacy bounds use ``sample`` ({"fit": sorted
    excesses, "holdout": sorted excesses}) instead of the stored null (None: the stored)."""
    token = _ACTIVE.set(sample)
    try:
        yield
    finally:
        _ACTIVE.reset(token)


def using_null_now(sample: dict | None) -> None:
    """From here on in this context (until the enclosing :func:`using_null` block ends), the
    tests use ``sample``."""
    _ACTIVE.set(sample)


def _null(holdout: bool, shift: np.ndarray | None) -> np.ndarray:
    """The null sample in use (sorted; :func:`using_null`), or every sum of one of its
    values and a ``shift`` draw (the model's own replay misfit, :mod:`replay`), sorted."""
    x = (_ACTIVE.get() or _null_sample())["holdout" if holdout else "fit"]
    if shift is None or np.size(shift) == 0:
        return x
    return np.sort((x[:, None] + np.asarray(shift, float)[None, :]).ravel())


def null_quantile(holdout: bool = False, level: float = 1.0 - ALPHA,
                  shift: np.ndarray | None = None) -> float:
    """Excess J - 1 below which a new effect-free record's p-value exceeds ``1 - level``.

    The smallest x with (1 + #{null >= x}) / (n + 1) <= 1 - level is just above the
    k-th largest null value, k = floor((1 - level) (n + 1)) (conformal bound).
    ``shift``: draws of the model's own replay misfit added to the null (:func:`_null`).
    """
    x = _null(holdout, shift)
    k = int(math.floor((1.0 - level) * (x.size + 1)))
    return float(x[-k]) if k >= 1 else math.inf


def gap_p_value(excess: float, holdout: bool = False,
                shift: np.ndarray | None = None) -> float:
    """Conformal p-value (1 + #{null >= excess}) / (n + 1): for an effect-free record
    exchangeable with the calibration records, P(p <= a) <= a for every a.  ``shift``:
    draws of the model's own replay misfit added to the null (:func:`_null`)."""
    x = _null(holdout, shift)
    return float((1 + np.count_nonzero(x >= excess)) / (x.size + 1))


def _g(rho: float) -> float:
    rho = min(max(rho, 0.0), 0.999)
    return (1.0 - rho) / (1.0 + rho)


def _rho(x: np.ndarray, same: np.ndarray | None = None) -> float:
    """Lag-1 autocorrelation (uncentred: the mean is part of the misfit) of ``x``."""
    if x.size < 3:
        return 0.0
    a, b = x[:-1], x[1:]
    if same is not None:
        a, b = a[same], b[same]
    den = float(np.sum(x * x))
    return float(np.sum(a * b) / den * x.size / max(a.size, 1)) if den > 0 else 0.0


def n_eff_profile(r: np.ndarray, frame: np.ndarray) -> float:
    """Effective number of independent profile residuals ``r`` (frames ``frame``)."""
    rho_s = _rho(r, frame[:-1] == frame[1:])
    frames = np.unique(frame)
    means = np.array([np.mean(r[frame == f]) for f in frames])
    rho_t = _rho(means)
    return max(2.0, len(frames) * _g(rho_t) * (r.size / max(len(frames), 1)) * _g(rho_s))


def n_eff_force(f: np.ndarray) -> float:
    """Effective number of independent force residuals (W, 2)."""
    return max(2.0, sum(f.shape[0] * _g(_rho(f[:, k])) for k in range(f.shape[1])))


def likelihood_ratio(J_base: dict, J_eff: dict, n_eff: dict) -> float:
    """LR = sum over observables of n_eff ln(J_base / J_eff)."""
    total = 0.0
    for o, n in n_eff.items():
        if J_base.get(o) and J_eff.get(o):
            total += n * math.log(J_base[o] / J_eff[o])
    return total


def chi2_sf(x: float, k: int) -> float:
    from scipy.stats import chi2
    return float(chi2.sf(max(x, 0.0), max(k, 1)))


def bonferroni_p(LR: float, k: int, m: int = 1) -> float:
    """The likelihood-ratio p-value of ``LR`` on ``k`` parameters (chi^2), Bonferroni-corrected
    over ``m`` candidates."""
    return min(1.0, chi2_sf(LR, k) * m)
