"""The naming rule against a model-form floor (issue 46, point 3): an effect is named when,
with its prior, it explains most of the baseline's excess on the fit and the holdout
records, and what it leaves is clearly less than what the best other effect leaves.

Continuous where it can be (docs/diagnosis.md, "Naming against the floor"):

* **Remainders, not a margin of shares.**  Candidate c leaves r(c) = max(J_c - 1, 0) of the
  baseline's excess R_b = J_b - 1 (fit records; r_h, R_bh on the holdout), as a share
  u(c) = max(r / R_b, r_h / R_bh): the worse of the records it was fitted to and the ones it
  was not (:func:`left`; a candidate is only as good as the holdout lets it be).  The lead
  is clear of the runner-up when their effective remainders' ratio

      rho = ((u(runner) + pi(runner)) R_b + q) / ((u(lead) + pi(lead)) R_b + q) >= RATIO  (N1)

  with q the floor's 95 % quantile (a remainder within the floor counts as the floor: the
  ratio of two remainders that are both noise is near 1, and never infinite).  A lead that
  leaves 1 % against a runner-up's 21 % has rho ~ 21 where the old margin of shares read
  0.1997 < 0.2.  The rivals (:func:`rivals`) are the checked explanations sharing no effect
  with the lead and, for a pair, its own parts: a pair is named only where it clearly beats
  the simpler explanation inside it (before, a pair's parts were no rivals of it, and every
  other effect shared a name with it, so a pair that left more than its better part was
  named with no rival at all).
* **A prior range on each effect's size** (:data:`PRIOR`): a value beyond the range a real
  cell plausibly has costs pi(c) = sum_k ((|v_k| - hi_k) / hi_k)_+^2 of the baseline's
  excess (N2), so a -40 % mass error (range 25 %) pays 0.36 R_b and loses to an effect of a
  plausible size that explains as much.  The baseline's own tolerances are already bounds
  of its fit (|u| <= 1), so they cost nothing here.
* **Most**: the effective share e = 1 - r / R_b - pi (N3) on the fit and on the holdout
  records, each >= MOST.

:func:`judge` returns every figure (shares, ratio, the prior's cost) beside the verdict, so a
report says how far from each threshold a verdict stands; :func:`moved` gives the rule with
one threshold moved (the +-20 % test of ``benchmarks/naming_thresholds.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

#: The plausible |value| of each effect (upper end per parameter, its unit as the effect's):
#: beyond it the prior (N2) costs. Friction coefficients of a sugar sheet on fondant, steel or
#: silicone 0.1-0.8; a bending stiffness of a 4 mm sheet EI <= 1.5e-5 N m^2; a Kelvin dashpot
#: within 1.5 times the benchmark's top; power-law index down to 0.45 (1 - n <= 0.55);
#: thinning b <= 2.5; a tool offset up to 3 mm (a calibrated robot); a mass error of 25 %
#: (a sheet weighed on a kitchen scale, its area measured by hand).
PRIOR: dict[str, tuple[float, ...]] = {
    "friction_mould": (0.8,), "friction_tool": (0.8,), "bending": (1.5e-5,),
    "kelvin_c1": (3000.0,), "power_law": (0.55,), "thinning": (2.5,),
    "tool_offset": (3e-3, 3e-3), "mass_error": (0.25,),
}


@dataclass(frozen=True)
class NamingRule:
    """The rule's thresholds: ``most`` (share, N3), ``ratio`` (N1), ``prior`` (a factor on
    the prior's cost N2; 1: as stated)."""

    most: float = 0.5
    ratio: float = 2.0
    prior: float = 1.0

    def __post_init__(self) -> None:
        for name, lo, hi in (("most", 0.0, 1.0), ("ratio", 1.0, 100.0), ("prior", 0.0, 100.0)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"NamingRule.{name} = {v!r}: expected {lo:g} to {hi:g}")


RULE = NamingRule()
#: The thresholds :func:`moved` moves.
THRESHOLDS = ("most", "ratio", "prior")


def moved(rule: NamingRule, name: str, factor: float) -> NamingRule:
    """``rule`` with threshold ``name`` times ``factor`` (``ratio``: its excess over 1, so that
    the ratio stays a ratio; ``most`` kept within 0-1)."""
    if name not in THRESHOLDS:
        raise ValueError(f"threshold {name!r}: expected one of {', '.join(THRESHOLDS)}")
    v = getattr(rule, name)
    new = 1.0 + (v - 1.0) * factor if name == "ratio" else v * factor
    if name == "most":
        new = min(new, 1.0)
    return replace(rule, **{name: new})


def prior_cost(values: dict) -> float:
    """pi (N2) of an explanation's ``values`` (effect name -> tuple of values) [share of the
    baseline's excess]; power_law is measured as 1 - n."""
    cost = 0.0
    for name, vals in values.items():
        for v, hi in zip(vals, PRIOR.get(name, ())):
            mag = abs(1.0 - v) if name == "power_law" else abs(v)
            cost += max(mag / hi - 1.0, 0.0) ** 2
    return cost


def _rem(J: float) -> float:
    return max(J - 1.0, 0.0) if math.isfinite(J) else math.inf


def effective_share(J: float, J_base: float, cost: float) -> float:
    """e (N3): the share of the baseline's excess ``J_base`` - 1 explained by a misfit ``J``,
    less the prior's ``cost``; nan without an excess."""
    if not (J_base > 1.0 and math.isfinite(J_base)):
        return math.nan
    return 1.0 - _rem(J) / (J_base - 1.0) - cost


@dataclass(frozen=True, kw_only=True)
class Naming:
    """The naming rule's figures for one lead (:func:`judge`): its effective shares (N3),
    the prior's cost (N2), the best rival and the remainders' ratio (N1), and the verdict."""

    explained_fit: float            # e on the fit records (N3)
    explained_holdout: float        # e on the holdout records (nan: none)
    prior_cost: float               # pi, share of the baseline's excess (N2)
    runner_up: str | None           # the best other explanation's name
    runner_up_explained_fit: float | None
    remainder_ratio: float          # rho (N1; inf: no rival)
    most: bool                      # e >= rule.most on fit and holdout records
    clear: bool                     # rho >= rule.ratio
    rule: NamingRule

    @property
    def named(self) -> bool:
        """Most of the excess, clearly the best: the lead is named."""
        return self.most and self.clear

    def as_json(self) -> dict:
        return {"explained_fit": self.explained_fit,
                "explained_holdout": self.explained_holdout, "prior_cost": self.prior_cost,
                "runner_up": self.runner_up,
                "runner_up_explained_fit": self.runner_up_explained_fit,
                "remainder_ratio": self.remainder_ratio, "most": self.most,
                "clear": self.clear, "rule": {"most": self.rule.most,
                                              "ratio": self.rule.ratio,
                                              "prior": self.rule.prior}}


def left(c, J_base: float, J_base_h: float, has_holdout: bool, cost: float) -> float:
    """What explanation ``c`` leaves of the baseline's excess, as a share, on the worse of the
    fit and the holdout records (each against its own baseline's excess), plus the prior's
    ``cost`` (N2): 1 - e of :func:`effective_share` on the worse side.  A candidate is only
    as good as the records it was not fitted to let it be (a thinning at its bound took 41 %
    of the fit records' excess and made the holdout 47 % worse); where the holdout has no
    excess or no run, the fit records alone."""
    u = 1.0 - effective_share(c.J, J_base, 0.0)
    if has_holdout and J_base_h > 1.0 and math.isfinite(J_base_h) \
            and math.isfinite(c.J_holdout):
        u = max(u, 1.0 - effective_share(c.J_holdout, J_base_h, 0.0))
    return u + cost


def rivals(lead, effects: Sequence) -> list:
    """The explanations ``lead`` must be clearly better than (N1): every checked one that
    shares no effect with it, and, for a pair, each of its own parts (a pair is named only
    where it clearly beats the simpler explanation within it)."""
    mine = set(lead.names)
    return [c for c in effects if c is not lead and getattr(c, "checked", True)
            and math.isfinite(c.J)
            and (not set(c.names) & mine or (set(c.names) < mine and c.names))]


def judge(lead, effects: Sequence, J_base: float, J_base_h: float, has_holdout: bool,
          q95: float, rule: NamingRule = RULE) -> Naming:
    """Is ``lead`` named?  ``effects``: the other candidates (:func:`rivals`: those sharing an
    effect with the lead are not its rivals unless they are a pair's parts; unchecked or
    failed ones neither); ``q95``: the floor's 95 % quantile of J - 1 on the fit records.
    Each explanation's remainder is what it leaves on the worse of the fit and holdout
    records (:func:`left`).  Returns the figures and ``most``, ``clear``."""
    q = max(q95, 0.0) if math.isfinite(q95) else 0.0
    Rb = max(J_base - 1.0, 0.0)
    cost = rule.prior * prior_cost(lead.values)
    fit = effective_share(lead.J, J_base, cost)
    hold = effective_share(lead.J_holdout, J_base_h, cost) if has_holdout else math.nan
    others = rivals(lead, effects)

    def eff_rem(c) -> float:
        if not (J_base > 1.0 and math.isfinite(J_base)):
            return _rem(c.J) + rule.prior * prior_cost(c.values) * Rb + q
        return left(c, J_base, J_base_h, has_holdout,
                    rule.prior * prior_cost(c.values)) * Rb + q
    runner = min(others, key=eff_rem) if others else None
    ratio = eff_rem(runner) / eff_rem(lead) if runner is not None and eff_rem(lead) > 0 \
        else math.inf
    most = fit >= rule.most and (not has_holdout or not math.isfinite(J_base_h)
                                 or hold >= rule.most)
    return Naming(explained_fit=fit, explained_holdout=hold, prior_cost=cost,
                  runner_up="+".join(runner.names) if runner is not None else None,
                  runner_up_explained_fit=(effective_share(runner.J, J_base,
                                                           rule.prior * prior_cost(runner.values))
                                           if runner is not None else None),
                  remainder_ratio=ratio, most=bool(most), clear=bool(ratio >= rule.ratio),
                  rule=rule)


def lead_key(J_base: float, rule: NamingRule = RULE):
    """The order of the lead against a model-form floor: checked first, then the least
    effective remainder J - 1 + pi R_b (the prior's cost in misfit units)."""
    Rb = max(J_base - 1.0, 0.0) if math.isfinite(J_base) else 0.0

    def key(c) -> tuple:
        J = c.J if math.isfinite(c.J) else math.inf
        return (not c.checked, J + rule.prior * prior_cost(c.values) * Rb)
    return key
