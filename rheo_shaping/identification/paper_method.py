"""The paper's three-step identification of k1, c1, c2 (Sec. 3.4).

1. ``c2`` from creep residuals, Eq. 10: ``c2 = F t1 / x2(t -> inf)``
   (:func:`c2_from_creep`), with the standard error from the spread of the
   tests.
2. ``c1`` from the force at the start of a tensile test, Eq. 11
   (:func:`c1_from_tensile`).  When F(0) is not significantly above zero the
   model is the Maxwell model (c1 = 0), as the paper concludes for fondant.
3. ``k1`` by linear least squares on Eq. 12-13, ``Y + b X = 0`` with
   ``b = k1/(c1+c2)``, over the tensile curves up to crack initiation
   (:func:`k1_by_linear_least_squares`; crack: :mod:`rheo_shaping.identification.crack`).

:func:`identify_paper` runs the three.  Constants are reported for the
0.1 m specimen (:data:`SPECIMEN_LENGTH_M`); data of other lengths are scaled.

Beyond the paper, applied to every tensile curve: the load-cell offset is the
mean of the samples at rest (``t <= 0``) and is subtracted (the paper assumes
a zeroed load cell; a curve without samples at rest is taken as zeroed).
The joint nonlinear fit is :mod:`rheo_shaping.identification.joint_fit`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..material.closed_forms import linearised_tensile
from .crack import CrackDetection, detect_crack
from .estimates import Estimate, symmetric, t_quantile
from ..material.three_element import SPECIMEN_LENGTH_M
from .material_data import CreepCurve, CreepResiduals, TensileCurve

#: F(0) counts as zero (Maxwell model, Eq. 11) below this many standard errors.
F0_SIGNIFICANCE = 2.0


@dataclass(frozen=True, eq=False)
class PreparedCurve:
    """A tensile curve cut at crack initiation, with its load-cell offset.

    ``t``, ``force`` [s, N]: the kept samples (``t <= 0`` at rest, then the
    pull up to crack initiation), offset not removed; ``offset`` [N] and its
    standard error (``None`` without samples at rest); ``speed`` [m/s];
    ``length`` [m]; ``crack``: the detection.
    """

    t: np.ndarray
    force: np.ndarray
    speed: float
    length: float
    offset: float | None
    offset_se: float | None
    crack: CrackDetection
    source: str

    @property
    def pull(self) -> np.ndarray:
        """Mask of the samples of the pull (t > 0)."""
        return self.t > 0.0

    @property
    def zeroed_force(self) -> np.ndarray:
        """Force minus the offset (offset 0 when unknown) [N]."""
        return self.force - (self.offset or 0.0)


def prepare_tensile(curve: TensileCurve) -> PreparedCurve:
    """Cut ``curve`` at crack initiation and measure its offset on the samples at rest."""
    crack = detect_crack(curve.t, curve.force)
    t, F = curve.t[: crack.keep], curve.force[: crack.keep]
    rest = F[t <= 0.0]
    if rest.size >= 2:
        offset, offset_se = float(rest.mean()), float(rest.std(ddof=1) / math.sqrt(rest.size))
    elif rest.size == 1:
        offset, offset_se = float(rest[0]), None
    else:
        offset, offset_se = None, None
    return PreparedCurve(t, F, curve.speed, curve.length, offset, offset_se, crack, curve.source)


# ----------------------------------------------------------------- step 1
def residuals_from_creep_curves(curves: list[CreepCurve]) -> CreepResiduals | None:
    """Creep curves that end unloaded as residual rows (Eq. 9-10 with F t1 = the impulse).

    The residual is the last measured elongation; it is only the plastic part
    if the recovery has finished by then.  Curves still loaded at their end
    are skipped.  ``None`` when no curve qualifies.
    """
    rows = []
    for c in curves:
        if c.force[-1] != 0.0:
            continue
        dt = np.diff(c.t)
        f = c.force[:-1] if c.hold == "step" else 0.5 * (c.force[:-1] + c.force[1:])
        impulse = float(np.sum(f * dt))
        t_on = float(np.sum(dt[f > 0.0]))
        if impulse <= 0.0 or c.elongation[-1] <= 0.0:
            continue
        rows.append((impulse / t_on, t_on, float(c.elongation[-1]) * SPECIMEN_LENGTH_M / c.length))
    if not rows:
        return None
    a = np.array(rows)
    return CreepResiduals(a[:, 0], a[:, 1], a[:, 2], SPECIMEN_LENGTH_M, "creep curves")


def merge_residuals(tables: list[CreepResiduals]) -> CreepResiduals:
    """One table of several (all scaled to the 0.1 m specimen)."""
    F = np.concatenate([t.force for t in tables])
    t1 = np.concatenate([t.t1 for t in tables])
    x = np.concatenate([t.residual * SPECIMEN_LENGTH_M / t.length for t in tables])
    return CreepResiduals(F, t1, x, SPECIMEN_LENGTH_M, "; ".join(t.source for t in tables))


def c2_from_creep(data: CreepResiduals) -> Estimate:
    """Step 1, Eq. 10: c2 [N s/m] on the 0.1 m specimen from creep residuals.

    With the compliance per test ``y_i = x_i/(F_i t1_i)`` [m/(N s)] (Eq. 9:
    ``y = 1/c2``), ``c2 = 1/mean(y)``; for tests with equal F and t1 this is
    the paper's ``F t1 / mean(x)``.  Standard error by the delta method from
    the spread of the tests (sample sd, ddof = 1); the 95 % interval maps the
    Student-t interval of ``mean(y)`` through ``1/y``.  A single test has no
    spread: ``se = None``.
    """
    y = data.residual / (data.force * data.t1)
    n = y.size
    m = float(y.mean())
    c2 = 1.0 / m * data.length / SPECIMEN_LENGTH_M
    note = f"Eq. 10 over {n} creep test(s)"
    if n < 2:
        return Estimate(c2, None, None, "N s/m", note + " (no spread from one test)")
    se_m = float(y.std(ddof=1)) / math.sqrt(n)
    scale = data.length / SPECIMEN_LENGTH_M
    q = t_quantile(n - 1)
    lo = scale / (m + q * se_m)
    hi = scale / (m - q * se_m) if m - q * se_m > 0.0 else None
    return Estimate(c2, c2 * se_m / m, (lo, hi), "N s/m", note)


# ----------------------------------------------------------------- step 2
@dataclass(frozen=True)
class InitialForce:
    """F(0+) [N] of one curve (offset removed) by extrapolation, with its standard error."""

    F0: float
    se: float
    speed: float
    length: float
    window_s: float


def initial_force(curve: PreparedCurve, fraction: float = 0.4,
                  min_points: int = 8) -> InitialForce | None:
    """Extrapolate the start of the pull to F(0+) [N] (Eq. 11's left side).

    A cubic in t is fitted to the pull samples in the first ``fraction`` of
    the kept pull (at least ``min_points`` samples); its value at t = 0 minus
    the offset is F(0+).  (A quadratic over a shorter window is biased
    upwards by the curvature of Eq. 5 by about its own standard error: it
    would call a Maxwell material three-element.)  ``None`` if the curve has
    too few samples.
    """
    pull = curve.pull
    tp, Fp = curve.t[pull], curve.zeroed_force[pull]
    if tp.size < min_points:
        return None
    window = max(fraction * tp[-1], tp[min(min_points, tp.size) - 1])
    sel = tp <= window
    X = np.vander(tp[sel], 4)
    coef, *_ = np.linalg.lstsq(X, Fp[sel], rcond=None)
    res = Fp[sel] - X @ coef
    dof = max(int(sel.sum()) - 4, 1)
    cov = float(res @ res) / dof * np.linalg.inv(X.T @ X)
    var = cov[3, 3] + (curve.offset_se or 0.0) ** 2
    return InitialForce(float(coef[3]), math.sqrt(var), curve.speed, curve.length, float(window))


def c1_from_tensile(curves: list[PreparedCurve],
                    c2: Estimate) -> tuple[Estimate, list[InitialForce]]:
    """Step 2, Eq. 11: c1 [N s/m] from F(0+) of the tensile curves.

    ``a = F0/v`` [N s/m] is averaged over the curves (weights 1/se^2, on the
    0.1 m specimen); Eq. 11 gives ``c1 = c2 a/(c2 - a)``.  If ``a`` is not
    more than :data:`F0_SIGNIFICANCE` standard errors above zero, F(0) = 0 as
    in the paper and c1 = 0 (Maxwell model); the interval then gives the
    largest c1 the data allow.
    """
    fits = [f for f in (initial_force(c) for c in curves) if f is not None]
    if not fits or c2.value is None:
        return Estimate.missing("N s/m", "needs a tensile curve and c2"), fits
    a_i = np.array([f.F0 / f.speed * f.length / SPECIMEN_LENGTH_M for f in fits])
    se_i = np.array([f.se / f.speed * f.length / SPECIMEN_LENGTH_M for f in fits])
    w = 1.0 / np.maximum(se_i, 1e-300) ** 2
    a = float(np.sum(w * a_i) / np.sum(w))
    se_a = float(1.0 / math.sqrt(np.sum(w)))
    C2 = c2.value
    se_c2 = c2.se or 0.0
    q = 1.96
    if a >= C2:
        return Estimate.missing("N s/m", f"F(0)/v = {a:.4g} N s/m >= c2: no three-element "
                                         "explanation"), fits

    def c1_of(a_: float) -> float:
        a_ = min(max(a_, 0.0), 0.999999 * C2)
        return C2 * a_ / (C2 - a_)

    da = C2 ** 2 / (C2 - max(a, 0.0)) ** 2
    dc2 = max(a, 0.0) ** 2 / (C2 - max(a, 0.0)) ** 2
    se = math.hypot(da * se_a, dc2 * se_c2)
    if a <= F0_SIGNIFICANCE * se_a:
        note = (f"Eq. 11: F(0)/v = {a:.3g} +- {se_a:.2g} N s/m over {len(fits)} curve(s), "
                f"not significantly > 0: Maxwell model, c1 = 0")
        return Estimate(0.0, se, (0.0, c1_of(max(a, 0.0) + q * se_a)), "N s/m", note), fits
    note = f"Eq. 11: F(0)/v = {a:.4g} +- {se_a:.2g} N s/m over {len(fits)} curve(s)"
    return Estimate(c1_of(a), se, (c1_of(a - q * se_a), c1_of(a + q * se_a)), "N s/m", note), fits


# ----------------------------------------------------------------- step 3
def eq13_points(curves: list[PreparedCurve], c1: float,
                c2: float) -> tuple[np.ndarray, np.ndarray]:
    """Pooled (X, Y) of Eq. 13 over the pull samples, with the points without a logarithm
    dropped."""
    Xs, Ys = [], []
    for c in curves:
        s = SPECIMEN_LENGTH_M / c.length            # constants of this curve's length
        X, Y = linearised_tensile(c.t[c.pull], c.zeroed_force[c.pull], c1 * s, c2 * s, c.speed)
        ok = np.isfinite(Y)
        Xs.append(X[ok])
        Ys.append(Y[ok])
    return np.concatenate(Xs), np.concatenate(Ys)


def _slope(curves, c1: float, c2: float) -> tuple[float, float, int]:
    X, Y = eq13_points(curves, c1, c2)
    sxx = float(X @ X)
    b = -float(X @ Y) / sxx
    r = Y + b * X
    n = X.size
    s2 = float(r @ r) / max(n - 1, 1)
    return b, math.sqrt(s2 / sxx), n


def k1_by_linear_least_squares(curves: list[PreparedCurve], c1: Estimate,
                               c2: Estimate) -> tuple[Estimate, Estimate]:
    """Step 3, Eq. 12-13: ``(k1 [N/m], b [1/s])`` by least squares of ``Y + b X = 0``.

    ``b = -sum(XY)/sum(X^2)`` (a line through the origin, as Eq. 12) and
    ``k1 = b (c1 + c2)`` on the 0.1 m specimen.  The standard error of k1
    combines the regression's (from its residuals) with those of c1 and c2,
    propagated through the whole step by central differences (their
    correlation is neglected).
    """
    if not curves or c1.value is None or c2.value is None:
        return (Estimate.missing("N/m", "needs a tensile curve, c1 and c2"),
                Estimate.missing("1/s", "needs a tensile curve, c1 and c2"))
    C1, C2 = c1.value, c2.value
    b, se_b, n = _slope(curves, C1, C2)
    if n < 3:
        return (Estimate.missing("N/m", "fewer than 3 usable points"), Estimate.missing("1/s", ""))

    def k1_of(c1_: float, c2_: float) -> float:
        return _slope(curves, c1_, c2_)[0] * (c1_ + c2_)

    k1 = b * (C1 + C2)
    h2 = 1e-4 * C2
    dk_dc2 = (k1_of(C1, C2 + h2) - k1_of(C1, C2 - h2)) / (2 * h2)
    dk_dc1 = (k1_of(C1 + h2, C2) - k1) / \
        h2 if C1 < h2 else (k1_of(C1 + h2, C2) - k1_of(C1 - h2, C2)) / (2 * h2)
    se_k1 = math.sqrt(((C1 + C2) * se_b) ** 2 + (dk_dc2 * (c2.se or 0.0))
                      ** 2 + (dk_dc1 * (c1.se or 0.0)) ** 2)
    note = f"Eq. 12-13 over {n} points; b = {b:.4g} +- {se_b:.2g} 1/s"
    return (symmetric(k1, se_k1, "N/m", n - 1, note, lower=0.0),
            symmetric(b, se_b, "1/s", n - 1, "Eq. 12-13", lower=0.0))


# ------------------------------------------------------------------ all
@dataclass(frozen=True, eq=False)
class PaperIdentification:
    """Result of :func:`identify_paper` (constants on the 0.1 m specimen).

    ``model``: ``"maxwell"`` (c1 = 0), ``"three-element"``, or ``None`` when
    c1 is not determined (no tensile curve).
    """

    k1: Estimate
    c1: Estimate
    c2: Estimate
    b: Estimate
    model: str | None
    curves: list[PreparedCurve] = field(default_factory=list)
    initial_forces: list[InitialForce] = field(default_factory=list)
    creep: CreepResiduals | None = None


def identify_paper(creep: CreepResiduals | None, tensile: Sequence[TensileCurve] = (),
                   creep_curves: Sequence[CreepCurve] = ()) -> PaperIdentification:
    """The three steps of Sec. 3.4 on the given data (creep residuals are required)."""
    tables = [creep] if creep is not None else []
    from_curves = residuals_from_creep_curves(list(creep_curves))
    if from_curves is not None:
        tables.append(from_curves)
    if not tables:
        raise ValueError("the paper's method needs creep residuals (Eq. 10): a creep residual "
                         "table, "
                         "or creep curves that end unloaded")
    data = merge_residuals(tables)
    c2 = c2_from_creep(data)
    curves = [prepare_tensile(c) for c in tensile]
    c1, f0s = c1_from_tensile(curves, c2)
    k1, b = k1_by_linear_least_squares(curves, c1, c2)
    model = None if c1.value is None else ("maxwell" if c1.value == 0.0 else "three-element")
    return PaperIdentification(k1, c1, c2, b, model, curves, f0s, data)
