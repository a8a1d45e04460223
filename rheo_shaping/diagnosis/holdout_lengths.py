"""Each candidate's holdout records with their laid rest lengths fitted under its own cell
(:func:`holdout_lengths`), the last step of checking a candidate (:mod:`.check`)."""
from __future__ import annotations

import math

import numpy as np

from .candidates import Explanation
from .context import FitContext
from .evaluate import Task, all_ok, apply
from .laid_length import fit_offsets, length_fitted, with_offsets


def holdout_lengths(cands: list[Explanation], ctx: FitContext) -> None:
    """Each candidate's holdout records with their laid rest lengths fitted under its own
    cell (its sheet knobs and its effect), then run again: a laid record's length is a
    nuisance of that record, fitted on its first seconds (:mod:`.laid_length`) under the
    cell being judged, as the baseline's holdout lengths are under the baseline's.  Without
    it a candidate whose knobs moved the bonds or the sag (which move the length) is judged
    on the holdout with the baseline's lengths, which only its fit records' knobs absorb.

    Only the holdout's own part of that refit is taken: its shift less the mean shift the
    fit records' lengths would take under the same cell (:func:`common_shift`).  The fit
    records keep the lengths they were fitted with, and the candidate's knobs were fitted on
    the whole records over them: the shift the first seconds ask of every record alike (the
    window's model-form bias, which the sag knob took on the whole records) is carried by the
    knobs on every record, the holdout included, and taken again on the holdout alone it is
    counted twice (seed 26004 case 78: +0.54 mm on all three records under thinning, holdout
    J 1.08 -> 3.66).  Nothing to do without laid holdout records."""
    H, nh, n_s = ctx.H, len(ctx.hold_d), ctx.n_s
    if H is None or not any(length_fitted(d) for d in ctx.hold_d):
        return
    todo = [c for c in cands if c.checked and math.isfinite(c.J) and not c.chain_free
            and c.baseline_u is not None]
    if not todo:
        return
    nd, nf = len(ctx.data), ctx.nf
    params_all = [apply(ctx.params(d, c.fitted_u[:n_s]), c.candidate)
                  for c in todo for d in ctx.data]
    shifts = fit_offsets([d for _ in todo for d in ctx.data], params_all, ctx.run.map)
    data, params = [], []
    for i, c in enumerate(todo):
        sh = shifts[i * nd:(i + 1) * nd]
        common = common_shift(ctx.fit_d, sh[:nf])
        data += with_offsets(ctx.hold_d, [x - common if length_fitted(d) else 0.0
                                          for d, x in zip(ctx.hold_d, sh[nf:])])
        params += params_all[i * nd + nf:(i + 1) * nd]
    outs = ctx.run([Task(d, p) for d, p in zip(data, params)])
    for i, c in enumerate(todo):
        o = outs[i * nh:(i + 1) * nh]
        if not all_ok(o):
            continue
        c.search.zh_raw = H.z(o)
        c.J_holdout = H.J_with_chain(c.search.zh_raw, c.fitted_u[n_s:])


def common_shift(fit_d, shifts) -> float:
    """The mean rest-length shift [m] of the fit records whose lengths are fitted
    (:func:`~.laid_length.length_fitted`), 0 when none is: the part of a cell's refit every
    record asks alike, which the knobs carry (:func:`holdout_lengths`)."""
    own = [float(x) for d, x in zip(fit_d, shifts) if length_fitted(d)]
    return float(np.mean(own)) if own else 0.0
