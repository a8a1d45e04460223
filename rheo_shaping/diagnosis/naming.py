"""The naming rule against a model-form floor: an effect is named when, with its prior, what
it leaves is clearly less than what the baseline leaves and than what the best other
explanation leaves, on the fit and the holdout records alike.

One threshold on one continuous figure (docs/diagnosis.md, "Naming against the floor"):

* **Remainders and their ratio.**  Candidate c leaves r(c) = max(J_c - 1, 0) of the
  baseline's excess R_b = J_b - 1 (fit records; r_h, R_bh on the holdout), as a share
  u(c) = max(r / R_b, r_h / R_bh) plus the prior's cost (N2): the worse of the records it
  was fitted to and the ones it was not (:func:`left`).  The lead (the candidate of least
  u, :func:`lead_key`) is named when for every rival

      rho = (u(rival) R_b + a) / (u(lead) R_b + a) >= RATIO        (N1)

  The rivals (:func:`rivals`) are the baseline itself (u = 1: "the lead explains most" is
  the same ratio against no effect at all, so there is no second threshold on shares), the
  checked explanations sharing no effect with the lead and, for a pair, its own parts (a
  pair is named only where it clearly beats the simpler explanation inside it).
* **The floor's level a**, the median of the floor's effect-free excess: a remainder of the
  size an effect-free record of another form typically leaves counts as that size, so the
  ratio of two remainders that are both form is near 1, never infinite.  It is the median,
  not the floor's 95 % quantile: with the quantile in both remainders a lead could not be
  clear of the baseline unless it left less than 1/2 - q95 / (2 R_b) of an excess R_b (69 %
  to explain where the excess was a few floors), a cap that refused effects explaining
  70-90 % against rivals explaining a quarter.  Whether there is a gap at all is the gap
  test's question (the 95 % quantile), not the naming rule's.
* **A prior range on each effect's size** (:data:`PRIOR`): a value beyond the range a real
  cell plausibly has costs pi(c) = sum_k ((|v_k| - hi_k) / hi_k)_+^2 of the baseline's
  excess (N2), so a -40 % mass error (range 25 %) pays 0.36 R_b and loses to an effect of a
  plausible size that explains as much.  The baseline's own tolerances are already bounds
  of its fit (|u| <= 1), so they cost nothing here.

:func:`judge` returns every figure (shares, ratio, the prior's cost) beside the verdict, so a
report says how far from the threshold a verdict stands; :func:`moved` gives the rule with
one of its constants moved (the +-20 % test of ``benchmarks/naming_thresholds.py``).
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
    """The rule's constants: ``ratio`` (N1, the one threshold), ``prior`` (a factor on the
    prior's cost N2; 1: as stated), ``level`` (a factor on the floor's level a; 1: its
    median).  ``most``, the share of the excess a lead explains where its ratio against the
    baseline is ``ratio`` with no level, is 1 - 1 / ratio (reported; no threshold of its
    own)."""

    ratio: float = 2.0
    prior: float = 1.0
    level: float = 1.0

    def __post_init__(self) -> None:
        for name, lo, hi in (("ratio", 1.0, 100.0), ("prior", 0.0, 100.0),
                             ("level", 0.0, 100.0)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"NamingRule.{name} = {v!r}: expected {lo:g} to {hi:g}")

    @property
    def most(self) -> float:
        return 1.0 - 1.0 / self.ratio


RULE = NamingRule()
#: The constants :func:`moved` moves.
THRESHOLDS = ("ratio", "prior", "level")


def moved(rule: NamingRule, name: str, factor: float) -> NamingRule:
    """``rule`` with constant ``name`` times ``factor`` (``ratio``: its excess over 1, so that
    the ratio stays a ratio)."""
    if name not in THRESHOLDS:
        raise ValueError(f"threshold {name!r}: expected one of {', '.join(THRESHOLDS)}")
    v = getattr(rule, name)
    new = 1.0 + (v - 1.0) * factor if name == "ratio" else v * factor
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
    """The naming rule's figures for one lead (:func:`judge`): its effective shares, the
    prior's cost (N2), the best other explanation and the remainders' ratio against it and
    against the baseline (N1), and the verdict."""

    explained_fit: float            # e = 1 - r / R_b - pi on the fit records
    explained_holdout: float        # e on the holdout records (nan: none)
    prior_cost: float               # pi, share of the baseline's excess (N2)
    runner_up: str | None           # the best other explanation's name
    runner_up_explained_fit: float | None
    remainder_ratio: float          # rho against the runner-up (N1; inf: no rival)
    most: bool                      # rho against the baseline >= rule.ratio
    clear: bool                     # rho against the runner-up >= rule.ratio
    rule: NamingRule

    @property
    def named(self) -> bool:
        """Clearly less left than the baseline and every rival leave: the lead is named."""
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
          level: float, rule: NamingRule = RULE) -> Naming:
    """Is ``lead`` named?  ``effects``: the other candidates (:func:`rivals`: those sharing an
    effect with the lead are not its rivals unless they are a pair's parts; unchecked or
    failed ones neither); ``level``: the floor's level a (the median of its effect-free
    excess J - 1 on the fit records, :meth:`.floor.Floor.level`).  Each explanation's
    remainder is what it leaves on the worse of the fit and holdout records (:func:`left`);
    the baseline leaves all of it.  Returns the figures and ``most`` (clear of the
    baseline), ``clear`` (clear of the best rival)."""
    a = rule.level * max(level, 0.0) if math.isfinite(level) else 0.0
    Rb = max(J_base - 1.0, 0.0)
    cost = rule.prior * prior_cost(lead.values)
    fit = effective_share(lead.J, J_base, cost)
    hold = effective_share(lead.J_holdout, J_base_h, cost) if has_holdout else math.nan
    others = rivals(lead, effects)

    def eff_rem(c) -> float:
        if not (J_base > 1.0 and math.isfinite(J_base)):
            return _rem(c.J) + rule.prior * prior_cost(c.values) * Rb + a
        return left(c, J_base, J_base_h, has_holdout,
                    rule.prior * prior_cost(c.values)) * Rb + a

    def over(r: float, mine: float) -> float:
        return r / mine if mine > 0 else (math.inf if r > 0 else 1.0)
    mine = eff_rem(lead)
    runner = min(others, key=eff_rem) if others else None
    ratio = over(eff_rem(runner), mine) if runner is not None else math.inf
    # the baseline as a rival (u = 1); a lead whose holdout did not run where the holdout has
    # an excess has not shown it explains it
    held = not has_holdout or not math.isfinite(J_base_h) or math.isfinite(hold)
    most = bool(over(Rb + a, mine) >= rule.ratio and math.isfinite(fit) and held)
    return Naming(explained_fit=fit, explained_holdout=hold, prior_cost=cost,
                  runner_up="+".join(runner.names) if runner is not None else None,
                  runner_up_explained_fit=(effective_share(runner.J, J_base,
                                                           rule.prior * prior_cost(runner.values))
                                           if runner is not None else None),
                  remainder_ratio=ratio, most=most, clear=bool(ratio >= rule.ratio),
                  rule=rule)


def lead_key(J_base: float, J_base_h: float = math.nan, rule: NamingRule = RULE):
    """The order of the lead against a model-form floor: checked first, then the least
    effective remainder, the one :func:`judge` judges by (:func:`left`: the worse of the fit
    and holdout records, ``J_base_h`` finite, plus the prior's cost; before, the fit
    records alone, so a lead the holdout refused could hide one it did not)."""
    Rb = max(J_base - 1.0, 0.0) if math.isfinite(J_base) else 0.0
    has_h = math.isfinite(J_base_h)

    def key(c) -> tuple:
        cost = rule.prior * prior_cost(c.values)
        if not math.isfinite(c.J):
            return (not c.checked, math.inf)
        if Rb > 0:
            return (not c.checked, left(c, J_base, J_base_h, has_h, cost))
        return (not c.checked, c.J + cost * Rb)
    return key
