"""Is what a candidate leaves effect-free?  :func:`adequate` (within the null plus the
model's own discretisation allowance, :mod:`.check`'s ``NUMERICS_FACTOR`` and
``GAP_SHARE``) and :func:`needs_numerics` (when the refined run is worth its cost)."""
from __future__ import annotations

import math

from . import stats
from .check import GAP_SHARE, NUMERICS_FACTOR


def adequate(c, J_base_h: float, has_holdout: bool, base=None,
             replay: tuple = (None, None)) -> bool:
    """What ``c`` leaves looks like the effect-free baseline: its excess misfit within the
    null's 95 % quantile plus an allowance for the model's discretisation error at the
    effect, on the fit and the holdout records; the holdout records must also improve on
    the baseline.  The allowance is ``NUMERICS_FACTOR`` times the numerics ``c`` adds to the
    baseline's own (the null already holds that): the misfit of its refinement change less
    the baseline's (``J_num_added``, :func:`numerics`), measured only with ``base`` (the
    baseline's refined run beside it).  It is never more than ``GAP_SHARE`` of the
    baseline's excess: a model whose discretisation error were comparable to the effect
    itself would contradict its convergence study, so a candidate that leaves a large part
    of the gap is refused whatever its numerics.  ``replay`` (fit, holdout): draws of the
    model's own replay misfit on those records, added to the null (:mod:`replay`; None
    unless the written cell has a Kelvin dashpot)."""
    def allow(added: float, J_b: float) -> float:
        if base is None or not (math.isfinite(added) and math.isfinite(J_b)):
            return 0.0
        return min(NUMERICS_FACTOR * added, GAP_SHARE * max(J_b - 1.0, 0.0))
    J_b = base.J if base is not None else math.nan
    ok = c.J - 1.0 <= stats.null_quantile(shift=replay[0]) + allow(c.J_num_added, J_b)
    if ok and has_holdout and math.isfinite(J_base_h):
        ok = (c.J_holdout < J_base_h and c.J_holdout - 1.0
              <= stats.null_quantile(True, shift=replay[1])
              + allow(c.J_num_added_holdout, J_base_h))
    return bool(ok)


def needs_numerics(c, J_base_h: float, has_holdout: bool,
                   replay: tuple = (None, None)) -> bool:
    """``c`` is significant, improves the holdout records, and is refused without the
    numerics allowance: only then is the refined run worth its cost."""
    return (c.checked and math.isfinite(c.J) and c.p <= stats.ALPHA
            and not adequate(c, J_base_h, has_holdout, replay=replay)
            and (not has_holdout or not math.isfinite(J_base_h) or c.J_holdout < J_base_h))
