"""Gap figures: how far model and records part, before and after an effect is added.

Per group of records (``fit``, ``holdout``):

* ``profile_rms_m`` and ``profile_max_m``: RMS and largest |residual| of the
  measured profile points [m] (noise included), and ``profile_max_rel``: the
  largest one relative to the sheet's undeformed length (the paper's measure,
  Sec. 4.3: "maximum error ... with respect to the undeformed configuration");
* ``profile_systematic_m``: the RMS with the noise removed,
  sqrt(max(mean r^2 - s_p^2, 0));
* ``force_rms_N`` and ``force_systematic_N`` the same for the tool force;
* ``delta_error_m``: mean |Delta measured (last frame) - Delta model|;
* ``J``: the balanced noise-normalised misfit (1: within noise; profile and
  tool force weigh one half each, :mod:`stats`) and ``gap``:
  sqrt(max(J - 1, 0)), the systematic gap in units of the noise; ``shrink``
  (after only): 1 - gap_after / gap_before.
"""
from __future__ import annotations

import math

import numpy as np

from .figures import GapFigures, GapGroups


def _group(data, res, idx, sp, sf, before: GapFigures | None = None,
           after: bool = False) -> GapFigures | None:
    if not idx:
        return None
    prof = np.concatenate([res[i].profile for i in idx])
    forces = [res[i].force for i in idx if res[i].force is not None]
    length = float(np.mean([np.sum(res[i].run.rest_length) for i in idx]))
    out: dict = {
        "records": len(idx),
        "profile_rms_m": float(np.sqrt(np.mean(prof ** 2))),
        "profile_max_m": float(np.max(np.abs(prof))),
        "profile_max_rel": float(np.max(np.abs(prof)) / length),
        "profile_systematic_m": float(math.sqrt(max(np.mean(prof ** 2) - sp ** 2, 0.0))),
        "delta_error_m": float(np.mean([abs(res[i].delta_measured - res[i].delta_model)
                                        for i in idx]))}
    J_p = float(np.mean(prof ** 2) / sp ** 2)
    J = J_p
    if forces:
        f = np.concatenate([x.reshape(-1) for x in forces])
        out["force_rms_N"] = float(np.sqrt(np.mean(f ** 2)))
        out["force_systematic_N"] = float(math.sqrt(max(np.mean(f ** 2) - sf ** 2, 0.0)))
        J = 0.5 * (J_p + float(np.mean(f ** 2) / sf ** 2))
    out["J"] = float(J)
    out["gap"] = float(math.sqrt(max(out["J"] - 1.0, 0.0)))
    if after and before is not None:
        out["shrink"] = float(1.0 - out["gap"] / before.gap) if before.gap > 0 else math.nan
    return GapFigures(**out)


def figures(data, res, fit_idx, hold_idx, sp, sf, before: GapGroups | None = None
            ) -> GapGroups:
    """The fit and holdout groups' figures; with ``before``, each also gets ``shrink``."""
    b = before or GapGroups()
    after = before is not None
    return GapGroups(fit=_group(data, res, fit_idx, sp, sf, b.fit, after),
                     holdout=_group(data, res, hold_idx, sp, sf, b.holdout, after))
