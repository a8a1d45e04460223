"""The model-form floor: what the calibrated baseline leaves on effect-free records of a
world that differs from the model in form (issue 26, point 3).

A real cell never is the model: the stored numerics null (``stats.NULL_FILE``, a finer
chain of the model itself) measures numerics only, so every difference of form reads
as a gap there.  The floor is the baseline's excess J - 1 on effect-free records of the
dynamic world (``rheo_shaping_validation.worlds``: inertia, soft contact with friction, the sheet
laid and released, its own sensors), calibrated by ``benchmarks/diagnosis_floor.py``
into ``rheo_shaping/data/diagnosis_floor.json`` per configuration (diagnosis chain size,
record length, fit and holdout record counts).

* **Units.** Each calibration case stores what the baseline left in physical units
  (systematic profile RMS [m], tool-force RMS [N]); the floor is expressed in the
  records' own noise: excess = (sys_p^2 / s_p^2 + sys_f^2 / s_f^2) / 2, so a finer
  camera raises the floor in noise units as it should.
* **Configurations.** Chain sizes and record lengths between the calibrated ones take
  the largest 95 % quantile of the corners around them (conservative); fit record
  counts must be calibrated ones; holdout records (any count) are judged against the
  fit records' remainders in the holdout records' noise (a configuration that stores no
  held-out remainders, as the shipped file does not).  Anything else is refused with the
  command that calibrates it (:class:`FloorError`), never reused.
* **Reference records** (``diagnose --reference``): effect-free records of the user's
  own cell.  Their baseline (fitted on all but one, the last held out) gives the cell's
  own remainder in mm and N; the stored sample is scaled to it, observable by
  observable (the world gives the spread, the cell its level).
* **The decision** (:func:`judge`): ``none`` when the baseline's excess is within the
  floor (its conformal p-value > 0.05) or below the user's practical tolerance
  (systematic profile RMS [m] and tool-force RMS [N]); an effect is named by the rule of
  :mod:`.naming` (with a prior on its size, most of the baseline's excess on the fit and
  the holdout records, a remainder clearly below the best other effect's); else
  ``unexplained``.
* **The worst-case bound** (:func:`model_form_interval`): the largest shift of an effect's
  value a discrepancy as large as the floor's 95 % quantile, or as what the named effect
  leaves when that is larger, could cause (the discrepancy along the effect's response, the
  baseline's columns projected out).  It is reported beside the interval; the interval's
  model-form part is estimated from the records' own remainder (:mod:`.intervals`), and the
  bound widens it only where no remainder is at hand.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from . import stats
from .figures import Remainder

FLOOR_FILE = Path(__file__).resolve().parent.parent / "data" / "diagnosis_floor.json"
CALIBRATE = ("python benchmarks/diagnosis_floor.py --n-masses {n} --process-times {T:g} "
             "--groupings {nf}+1 --cases 24 --out FILE, then diagnose --floor FILE")


class FloorError(ValueError):
    """No floor is calibrated for the diagnosis's configuration (the message says what to
    run)."""


@dataclass(frozen=True)
class Floor:
    """Sorted excess samples (J - 1) for fit and holdout records, and where they come from."""

    fit: np.ndarray
    holdout: np.ndarray
    source: str
    config: dict = field(default_factory=dict)
    profile_sys_m: float = math.nan     # 95 % quantile of the profile remainder [m]
    force_sys_N: float = math.nan       # 95 % quantile of the tool-force remainder [N]

    @property
    def sample(self) -> dict | None:
        """The samples for :func:`stats.using_null` (None: the stored numerics null)."""
        if self.source == "numerics":
            return None
        return {"fit": self.fit, "holdout": self.holdout}

    def quantile(self, holdout: bool = False, shift=None) -> float:
        """The excess below which an effect-free record's p-value exceeds 0.05."""
        with stats.using_null(self.sample):
            return stats.null_quantile(holdout, shift=shift)

    def level(self) -> float:
        """The floor's level: the median of its effect-free excess J - 1 on the fit records,
        what a record of another form typically leaves (the naming rule's a,
        :func:`.naming.judge`); nan without a sample."""
        return float(np.median(self.fit)) if self.fit.size else math.nan

    def p_value(self, excess: float, holdout: bool = False, shift=None) -> float:
        with stats.using_null(self.sample):
            return stats.gap_p_value(excess, holdout, shift=shift)

    def as_dict(self) -> dict:
        return {"source": self.source, "config": self.config, "cases": int(self.fit.size),
                "q95_fit": self.quantile(), "q95_holdout": self.quantile(True),
                "q95_profile_m": self.profile_sys_m, "q95_force_N": self.force_sys_N}


@lru_cache(maxsize=4)
def _stored(path: str) -> dict:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise FloorError(f"floor file {path}: cannot be read ({exc}); expected the output "
                         "of benchmarks/diagnosis_floor.py") from None


def _excess(sys_p, sys_f, sp: float, sf: float, kp: float = 1.0, kf: float = 1.0) -> np.ndarray:
    """Excess J - 1 of remainders ``sys_p`` [m], ``sys_f`` [N] (scaled by ``kp``, ``kf``) in the
    noise ``sp`` [m], ``sf`` [N]."""
    p = (kp * np.nan_to_num(np.asarray(sys_p, float))) ** 2 / sp ** 2
    f = (kf * np.nan_to_num(np.asarray(sys_f, float))) ** 2 / sf ** 2 if math.isfinite(sf) \
        else np.zeros_like(p)
    return np.sort(0.5 * (p + f))


def _q95(x) -> float:
    x = np.sort(np.asarray(x, float))
    k = int(math.floor(0.05 * (x.size + 1)))
    return float(x[-k]) if k >= 1 and x.size else (float(x[-1]) if x.size else math.nan)


def _corners(values: list[float], v: float) -> list[float] | None:
    """The calibrated values around ``v`` (itself when calibrated); None outside them."""
    vs = sorted(set(values))
    if not vs or v < vs[0] - 1e-9 or v > vs[-1] + 1e-9:
        return None
    lo = max(x for x in vs if x <= v + 1e-9)
    hi = min(x for x in vs if x >= v - 1e-9)
    return sorted({lo, hi})


def select(n_masses: int, process_time: float, n_fit: int, n_holdout: int,
           path: Path | str = FLOOR_FILE) -> list[dict]:
    """The calibration configurations that cover this diagnosis (:class:`FloorError` if none:
    the message says how to calibrate it)."""
    data = _stored(str(path))
    cfgs = data.get("configs", [])
    how = CALIBRATE.format(n=n_masses, T=process_time, nf=n_fit)
    ns = _corners([c["n_masses"] for c in cfgs], n_masses)
    ts = _corners([c["process_time_s"] for c in cfgs], process_time)
    fits = sorted({c["n_fit"] for c in cfgs})
    if ns is None or ts is None or n_fit not in fits:
        raise FloorError(
            f"no model-form floor is calibrated for n_masses = {n_masses}, records of "
            f"{process_time:g} s, {n_fit} fit record(s) (calibrated: n_masses "
            f"{min(c['n_masses'] for c in cfgs) if cfgs else '-'}-"
            f"{max(c['n_masses'] for c in cfgs) if cfgs else '-'}, "
            f"{min(c['process_time_s'] for c in cfgs) if cfgs else '-'}-"
            f"{max(c['process_time_s'] for c in cfgs) if cfgs else '-'} s, fit records "
            f"{fits}): run `{how}`, or pass --reference RECORD... (effect-free records of "
            "this cell), or --floor numerics")
    out = [c for c in cfgs if c["n_masses"] in ns and c["process_time_s"] in ts
           and c["n_fit"] == n_fit]
    if not out:
        raise FloorError(f"no floor is calibrated at the corners around n_masses = {n_masses}, "
                         f"{process_time:g} s, {n_fit} fit record(s): run `{how}`")
    if n_holdout and not any(c["holdout"] for c in out):
        raise FloorError(f"no holdout floor is calibrated for n_masses = {n_masses}, "
                         f"{process_time:g} s, {n_fit} fit record(s): run `{how}`")
    return out


def stored_floor(n_masses: int, process_time: float, n_fit: int, n_holdout: int,
                 sp: float, sf: float, path: Path | str = FLOOR_FILE,
                 scale: tuple[float, float] = (1.0, 1.0), source: str | None = None) -> Floor:
    """The floor for a diagnosis of ``n_fit`` + ``n_holdout`` records of ``process_time`` [s]
    at ``n_masses``, in the records' noise ``sp`` [m], ``sf`` [N]; ``scale`` (profile,
    force): factors on the stored remainders (reference records)."""
    cfgs = select(n_masses, process_time, n_fit, n_holdout, path)
    kp, kf = scale
    best = None
    for c in cfgs:                          # the corner with the largest fit quantile
        fit = _excess(c["profile_sys_m"], c["force_sys_N"], sp, sf, kp, kf)
        hold = _excess(c.get("profile_sys_holdout_m", c["profile_sys_m"]),
                       c.get("force_sys_holdout_N", c["force_sys_N"]), sp, sf, kp, kf)
        if best is None or _q95(fit) > _q95(best[0]):
            best = (fit, hold, c)
    assert best is not None         # select() raises when no configuration covers it
    fit, hold, c = best
    cfg = {k: c[k] for k in ("n_masses", "process_time_s", "n_fit", "n_holdout", "cases")}
    return Floor(fit, hold, source or f"stored ({Path(path).name}, dynamic world)", cfg,
                 kp * _q95(np.nan_to_num(c["profile_sys_m"])),
                 kf * _q95(np.nan_to_num(c["force_sys_N"])))


def numerics_floor() -> Floor:
    """The stored numerics null (a finer chain of the model itself; ``stats.NULL_FILE``)."""
    s = stats._null_sample()
    return Floor(s["fit"], s["holdout"], "numerics", {"file": stats.NULL_FILE.name})


def reference_scale(ref_diag, n_masses: int, process_time: float,
                    path: Path | str = FLOOR_FILE) -> tuple[float, float]:
    """Factors (profile, force) from the stored remainders' medians to what the baseline left
    on the user's effect-free reference records (``ref_diag``: their diagnosis)."""
    cfgs = select(n_masses, process_time, len(ref_diag.records), 0, path)
    g = ref_diag.gap_baseline.fit
    ref_p = (g.profile_systematic_m if g is not None else 0.0) or 0.0
    ref_f = (g.force_systematic_N if g is not None else 0.0) or 0.0
    med_p = float(np.median(np.concatenate([np.nan_to_num(c["profile_sys_m"]) for c in cfgs])))
    med_f = float(np.median(np.concatenate([np.nan_to_num(c["force_sys_N"]) for c in cfgs])))
    return (max(ref_p / med_p, 1.0) if med_p > 0 else 1.0,
            max(ref_f / med_f, 1.0) if med_f > 0 else 1.0)


def within_tolerance(parts: dict, sp: float, sf: float,
                     tolerance: tuple[float, float] | None) -> bool:
    """The baseline's systematic remainders (profile [m], tool force [N]) are both below the
    user's practical ``tolerance`` (None: no tolerance)."""
    if tolerance is None:
        return False
    tp, tf = tolerance
    sys_p = sp * math.sqrt(max(parts.get("profile", 1.0) - 1.0, 0.0))
    sys_f = sf * math.sqrt(max(parts.get("tool force", 1.0) - 1.0, 0.0))
    return sys_p <= tp and sys_f <= tf


def remainder(J: float, parts: dict, sp: float, sf: float, floor: Floor,
              holdout: bool = False) -> Remainder:
    """What is left, in noise units, m and N, against the floor's 95 % quantile."""
    q = floor.quantile(holdout)
    sys_p = sp * math.sqrt(max(parts.get("profile", 1.0) - 1.0, 0.0)) if parts else math.nan
    sys_f = (sf * math.sqrt(max(parts.get("tool force", 1.0) - 1.0, 0.0))
             if parts and "tool force" in parts else math.nan)
    return Remainder(J_minus_1=J - 1.0, noise_units=math.sqrt(max(J - 1.0, 0.0)),
                     profile_systematic_m=sys_p, force_systematic_N=sys_f, floor_q95=q,
                     beyond_floor=bool(J - 1.0 > q))


def holdout_remainder(J_h: float, floor: Floor) -> Remainder:
    """What is left on the holdout records (excess alone) against the floor's holdout
    quantile."""
    q = floor.quantile(True)
    return Remainder(J_minus_1=J_h - 1.0, floor_q95=q, beyond_floor=bool(J_h - 1.0 > q))


def discrepancy_size(q95: float, J_named: float) -> float:
    """The squared size (balanced misfit units) of the model-form discrepancy an interval is
    widened for: the floor's 95 % quantile ``q95``, or what the named effect leaves on the fit
    records (``J_named`` - 1) when that is larger (a remainder beyond the floor is model form
    the floor does not hold)."""
    return max(q95, J_named - 1.0) if math.isfinite(J_named) else q95


def model_form_interval(c, q95: float, A: np.ndarray, responses) -> list[float]:
    """Widen single effect ``c``'s interval by the largest shift of its value a discrepancy
    of squared size ``q95`` (the floor's 95 % quantile, in the balanced misfit's units) can
    cause: sqrt(q95) / |e_perp| per parameter, e_perp its response column with the
    baseline's columns ``A`` projected out (Cauchy-Schwarz on the least-squares shift).
    Returns the widths added, per parameter (empty when none applies)."""
    from .check import effect_columns
    if len(c.names) != 1 or not (q95 > 0):
        return []
    name = c.names[0]
    cols = effect_columns(name, responses, c.values[name])
    if not cols:
        return []
    Q = np.linalg.qr(A, mode="reduced")[0]
    ivs = list(c.interval.get(name, [(v, v) for v in c.values[name]]))
    widths: dict[int, float] = {}
    for k, col in cols:
        perp = col - Q @ (Q.T @ col)
        n = float(np.linalg.norm(perp))
        if n <= 0 or k >= len(ivs):
            continue
        w = math.sqrt(q95) / n
        widths[k] = max(widths.get(k, 0.0), w)
    c.interval[name] = widened(name, ivs, widths)
    return [widths.get(k, 0.0) for k in range(len(ivs))]


def widened(name: str, ivs: list[tuple[float, float]],
            widths: dict[int, float]) -> list[tuple[float, float]]:
    """Intervals ``ivs`` of effect ``name`` with parameter k's widened by ``widths[k]`` on
    each side, within the effect's bounds."""
    from ..sheet.effects import EFFECTS
    out = list(ivs)
    for k, w in widths.items():
        lo, hi = out[k]
        b_lo, b_hi = EFFECTS[name].bounds[k]
        out[k] = (max(lo - w, b_lo), min(hi + w, b_hi))
    return out
