"""The search checks what it finds (issue 46, point 3): which single effects are checked by
simulation, and the refinement of every strong one to convergence before any verdict.

The linearised fits rank the effects by p and J; the p of a fit that trades a little
profile for much force reads as a loss (docs/diagnosis.md, "Naming against the floor"), so
a ranking by p alone can leave unchecked an effect whose first fit explains much (issue 46:
a tool friction whose first fit took 17 % of the excess was never simulated while the three
checked left more than the baseline).  :func:`to_check` takes the ``CHECKED`` best by p,
the ``CHECKED`` best by J, and every effect whose first fit explains at least
``CHECK_SHARE`` of the baseline's excess.  :func:`converge` then refines each checked
effect whose first fit or first simulation explains at least ``CHECK_SHARE`` from its own
Jacobian of the sheet knobs (:func:`check.relinearise`) by chord steps, again while a round
lowers its misfit J by more than ``CONVERGED`` of the baseline's excess (at most ``ROUNDS``
rounds): a strong effect's fit does not stop at a first step.
"""
from __future__ import annotations

import math
from typing import Sequence

from .candidates import CHECKED, Explanation
from .check import refine_points, relinearise
from .context import Baseline, FitContext

#: Share of the baseline's excess a first fit must explain to be checked whatever its rank.
CHECK_SHARE = 0.15
#: A refinement round that lowers J by less than this share of the baseline's excess ends it.
CONVERGED = 0.01
#: Refinement rounds (own Jacobian, then chord steps) at most per strong candidate.
ROUNDS = 3


def share(J: float, J_base: float) -> float:
    """The share of the baseline's excess ``J_base`` - 1 a misfit ``J`` explains (-inf when
    either is not finite or there is no excess)."""
    if not (math.isfinite(J) and math.isfinite(J_base) and J_base > 1.0):
        return -math.inf
    return (J_base - J) / (J_base - 1.0)


def to_check(effects: Sequence[Explanation], J_base: float) -> list[Explanation]:
    """The effects to simulate (``effects`` ranked by (p, J), their J the linearised fit's):
    the ``CHECKED`` first, the ``CHECKED`` of least J, every one explaining at least
    ``CHECK_SHARE``; in ``effects``' order, each once."""
    by_J = sorted(effects, key=lambda c: c.J if math.isfinite(c.J) else math.inf)
    want = {id(c) for c in list(effects[:CHECKED]) + by_J[:CHECKED]}
    want |= {id(c) for c in effects if share(c.J, J_base) >= CHECK_SHARE}
    return [c for c in effects if id(c) in want]


def strong(c: Explanation, J_base: float) -> bool:
    """``c``'s first fit (``search.first_J``) or its simulated J explains at least
    ``CHECK_SHARE`` of the baseline's excess."""
    return max(share(c.search.first_J, J_base), share(c.J, J_base)) >= CHECK_SHARE


def converge(checked: Sequence[Explanation], ctx: FitContext, base: Baseline,
             m: int, responses: dict) -> list[Explanation]:
    """Refine every :func:`strong` checked effect to convergence; returns them (each marked
    ``search.converged``)."""
    strong_ = [c for c in checked if c.checked and math.isfinite(c.J) and not c.chain_free
               and strong(c, base.J)]
    todo = list(strong_)
    tol = CONVERGED * max(base.J - 1.0, 0.0)
    for _ in range(ROUNDS):
        if not todo:
            break
        before = {id(c): c.J for c in todo}
        if ctx.sheet_lim > 0:
            relinearise(todo, ctx)
        refine_points(todo, ctx, base, m=m, responses=responses)
        todo = [c for c in todo if math.isfinite(c.J) and before[id(c)] - c.J > tol]
    for c in strong_:
        c.search.converged = True
    return strong_
