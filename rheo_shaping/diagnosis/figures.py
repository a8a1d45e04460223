"""The typed figures a :class:`~.result.Diagnosis` carries: the noise, the gap figures per
group of records (:mod:`.gap`), what is left against the floor, and the floor the verdict
was judged against (:mod:`.floor`).  Each is frozen and writes the JSON key for key
(``as_json``)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .naming import Naming


@dataclass(frozen=True, kw_only=True)
class Noise:
    """The records' noise: s_p [m] profile, s_f [N] tool force (MAD of second differences)."""

    profile_m: float
    force_N: float

    def as_json(self) -> dict:
        return {"profile_m": self.profile_m, "force_N": self.force_N}


@dataclass(frozen=True, kw_only=True)
class GapFigures:
    """How far model and records part over one group of records (:mod:`.gap`)."""

    records: int
    profile_rms_m: float            # RMS of the profile residuals [m], noise included
    profile_max_m: float            # largest |profile residual| [m]
    profile_max_rel: float          # the same over the sheet's undeformed length (Sec. 4.3)
    profile_systematic_m: float     # sqrt(max(mean r^2 - s_p^2, 0)) [m]
    delta_error_m: float            # mean |Delta measured - Delta model| [m]
    J: float                        # balanced misfit (1: within noise)
    gap: float                      # sqrt(max(J - 1, 0)), in noise units
    force_rms_N: float | None = None          # None: no record of the group has a wrench
    force_systematic_N: float | None = None
    shrink: float | None = None     # 1 - gap / gap before (after figures only; nan: no gap)

    def as_json(self) -> dict:
        out: dict = {"records": self.records, "profile_rms_m": self.profile_rms_m,
                     "profile_max_m": self.profile_max_m,
                     "profile_max_rel": self.profile_max_rel,
                     "profile_systematic_m": self.profile_systematic_m,
                     "delta_error_m": self.delta_error_m}
        if self.force_rms_N is not None:
            out["force_rms_N"] = self.force_rms_N
            out["force_systematic_N"] = self.force_systematic_N
        out["J"], out["gap"] = self.J, self.gap
        if self.shrink is not None:
            out["shrink"] = None if math.isnan(self.shrink) else self.shrink
        return out


@dataclass(frozen=True, kw_only=True)
class GapGroups:
    """Gap figures of the fit and the holdout records (None: no such records)."""

    fit: GapFigures | None = None
    holdout: GapFigures | None = None

    def group(self, name: str) -> GapFigures | None:
        """``fit`` or ``holdout``."""
        return {"fit": self.fit, "holdout": self.holdout}[name]

    def as_json(self) -> dict:
        return {k: None if g is None else g.as_json()
                for k, g in (("fit", self.fit), ("holdout", self.holdout))}


@dataclass(frozen=True, kw_only=True)
class Remainder:
    """What an explanation leaves, against the floor's 95 % quantile (None: not given for
    holdout records, whose remainder is the excess alone)."""

    J_minus_1: float                # excess misfit
    floor_q95: float                # the floor's 95 % quantile of J - 1
    beyond_floor: bool
    noise_units: float | None = None            # sqrt(max(J - 1, 0))
    profile_systematic_m: float | None = None   # [m] (nan: no parts)
    force_systematic_N: float | None = None     # [N] (nan: no tool force)

    def as_json(self) -> dict:
        if self.noise_units is None:
            return {"J_minus_1": self.J_minus_1, "floor_q95": self.floor_q95,
                    "beyond_floor": self.beyond_floor}
        return {"J_minus_1": self.J_minus_1, "noise_units": self.noise_units,
                "profile_systematic_m": self.profile_systematic_m,
                "force_systematic_N": self.force_systematic_N, "floor_q95": self.floor_q95,
                "beyond_floor": self.beyond_floor}


@dataclass(frozen=True, kw_only=True)
class FloorReport:
    """The floor a diagnosis was judged against and what the baseline and the verdict leave
    on it (:mod:`.floor`, :mod:`.naming`)."""

    source: str                     # "numerics", or where the model-form floor comes from
    config: dict                    # the calibration configuration it was taken from
    cases: int                      # calibration cases
    q95_fit: float                  # 95 % quantile of J - 1, fit records
    q95_holdout: float              # the same, holdout records
    q95_profile_m: float            # 95 % quantile of the profile remainder [m]
    q95_force_N: float              # the same of the tool force [N]
    baseline: Remainder
    below_tolerance: bool           # below the user's practical tolerance: nothing named
    tolerance: tuple[float, float] | None = None    # (profile [m], tool force [N])
    naming: Naming | None = None    # the naming rule's figures (model-form floors)
    baseline_holdout: Remainder | None = None
    verdict: Remainder | None = None
    verdict_holdout: Remainder | None = None
    model_form_interval_width: list[float] | None = None   # added to the verdict's interval
    model_form_discrepancy: float | None = None    # the bound's squared size (J - 1 units)
    model_form_spread: dict | None = None   # how the width was estimated (intervals.Spread)
    model_form_bound: dict | None = None    # the worst-case bound: widths, the interval
    level: float = math.nan         # the naming rule's floor level (median J - 1, fit records)

    @property
    def model_form(self) -> bool:
        """Judged against a model-form floor (not the numerics null)."""
        return self.source != "numerics"

    def as_json(self) -> dict:
        out: dict = {"source": self.source, "config": self.config, "cases": self.cases,
                     "q95_fit": self.q95_fit, "q95_holdout": self.q95_holdout,
                     "q95_profile_m": self.q95_profile_m, "q95_force_N": self.q95_force_N,
                     "baseline": self.baseline.as_json()}
        if self.baseline_holdout is not None:
            out["baseline_holdout"] = self.baseline_holdout.as_json()
        out["below_tolerance"] = self.below_tolerance
        out["tolerance"] = (None if self.tolerance is None else
                            {"profile_m": self.tolerance[0], "force_N": self.tolerance[1]})
        out["naming"] = None if self.naming is None else self.naming.as_json()
        if self.verdict is not None:
            out["verdict"] = self.verdict.as_json()
        if self.verdict_holdout is not None:
            out["verdict_holdout"] = self.verdict_holdout.as_json()
        if self.model_form_interval_width is not None:
            out["model_form_interval_width"] = self.model_form_interval_width
            out["model_form_discrepancy"] = self.model_form_discrepancy
            out["model_form_spread"] = self.model_form_spread
            out["model_form_bound"] = self.model_form_bound
        return out
