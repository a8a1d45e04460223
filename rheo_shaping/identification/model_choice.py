"""Which material model do the data support?  Maxwell, three-element, Burgers.

Each model is fitted jointly to the same data (:mod:`rheo_shaping.identification.joint_fit`);
the models are nested (Maxwell = three-element with c1 = 0 = Burgers with
c1 = 0 and k2 = inf), so each richer fit starts from the simpler optimum and
its likelihood can only be higher.  They are ranked by

* AIC = -2 ln L + 2 k (Akaike weights ``exp(-dAIC/2)`` normalised), and
* BIC = -2 ln L + k ln n, which penalises a parameter more (ln n > 2 for n > 7).

The chosen model is the BIC's: the simpler nested model unless the data
clearly need the extra element.  The extra parameter of a nested model sits on
its bound (c1 = 0, 1/k2 = 0), where the usual chi-square reasoning overstates
the evidence for it; BIC's heavier penalty is the safer side.  When no data
depend on more than c2 (creep residuals only), the models cannot be told
apart and no model is chosen.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence


from .estimates import Estimate
from .paper_method import PreparedCurve, merge_residuals, prepare_tensile
from .joint_fit import MODELS, FitData, ModelFit, fit_model
from .material_data import CreepCurve, CreepResiduals, TensileCurve


@dataclass(frozen=True, eq=False)
class JointIdentification:
    """Fits of every model, their ranking and the chosen constants.

    ``fits``: model -> :class:`ModelFit`; ``best_aic``, ``best_bic``: the
    models with the smallest criteria; ``model``: the chosen one (BIC), or
    ``None``; ``params``: its constants (k1, c1, c2, k2 [k2 inf unless
    Burgers]), where a Maxwell choice reports c1 = 0 with the upper bound the
    three-element fit allows.
    """

    fits: dict[str, ModelFit]
    best_aic: str | None
    best_bic: str | None
    model: str | None
    params: dict[str, Estimate]
    data: FitData
    notes: list[str] = field(default_factory=list)

    def table(self) -> list[dict]:
        """One row per model: k, n, log-likelihood, AIC, BIC, their differences, Akaike weight."""
        rows: list[dict] = []
        if not self.fits:
            return rows
        amin = min(f.aic for f in self.fits.values())
        bmin = min(f.bic for f in self.fits.values())
        w = {m: math.exp(-0.5 * (f.aic - amin)) for m, f in self.fits.items()}
        tot = sum(w.values())
        for m, f in self.fits.items():
            rows.append({"model": m, "k": f.k, "n": f.n, "loglik": f.loglik, "aic": f.aic,
                         "bic": f.bic,
                         "delta_aic": f.aic - amin, "delta_bic": f.bic - bmin,
                         "akaike_weight": w[m] / tot})
        return rows


def identify_joint(tensile: Sequence[TensileCurve] = (),
                   residuals: Sequence[CreepResiduals] = (),
                   creep_curves: Sequence[CreepCurve] = (), models: tuple[str, ...] = MODELS,
                   noise_rel: float = 0.01, noise_abs: float = 1e-3) -> JointIdentification:
    """Fit every model in ``models`` (in nesting order) and choose one by BIC."""
    curves: list[PreparedCurve] = [prepare_tensile(c) for c in tensile]
    res = merge_residuals(list(residuals)) if residuals else None
    data = FitData(curves, res, list(creep_curves), noise_rel, noise_abs)
    order = [m for m in MODELS if m in models]
    notes: list[str] = []
    fits: dict[str, ModelFit] = {}
    if not data.has_shape:
        fit = fit_model("maxwell", data)
        notes.append("only creep residuals: they fix c2 (Eq. 10) but no other constant, "
                     "and cannot tell the models apart")
        params = {"c2": fit.params["c2"],
                  "k1": Estimate.missing("N/m", "needs a tensile curve or a creep curve"),
                  "c1": Estimate.missing("N s/m", "needs a tensile curve or a creep curve"),
                  "k2": Estimate.missing("N/m", "needs a tensile curve or a creep curve")}
        return JointIdentification({}, None, None, None, params, data, notes)
    previous = None
    for m in order:
        fits[m] = fit_model(m, data, previous)
        previous = fits[m]
    best_aic = min(fits, key=lambda m: fits[m].aic)
    best_bic = min(fits, key=lambda m: fits[m].bic)
    if best_aic != best_bic:
        notes.append(
            f"AIC prefers {best_aic}, BIC prefers {best_bic}: the extra element is weakly "
            "supported")
    chosen = fits[best_bic]
    params = {k: v for k, v in chosen.params.items() if k in ("k1", "c1", "c2", "k2")}
    params.setdefault("k2", Estimate(math.inf, None, None,
                      "N/m", "no series spring in this model"))
    if best_bic == "maxwell" and "three-element" in fits:
        c1 = fits["three-element"].params["c1"]
        hi = None if c1.ci95 is None else c1.ci95[1]
        params["c1"] = Estimate(0.0, c1.se, (0.0, hi), "N s/m",
                                "Maxwell chosen (c1 = 0); the three-element fit gives c1 = "
                                f"{c1.value:.3g} N s/m")
    for m, f in fits.items():
        lost = [n for n in ("k1", "c1", "c2", "j2") if n in f.params and f.params[n].se is None
                and f.params[n].value is not None and not (n == "j2" and f.params[n].value == 0.0)
                and not f.params[n].note.startswith("fixed")]
        if lost:
            notes.append(f"{m}: {', '.join(lost)} not identifiable from these data")
    te = fits.get("three-element")
    if (te is not None and te.params["c1"].se is None
            and any(c.offset is None for c in data.curves)):
        notes.append("c1 and the load-cell offsets are confounded: without samples at rest (t <= "
                     "0) "
                     "or creep data a start-up jump F(0) (Eq. 11) looks like an offset, so the "
                     "Maxwell "
                     "constants hold only if the load cell was zeroed")
    for m, f in fits.items():
        if not f.success:
            notes.append(f"{m}: optimiser did not report convergence ({f.message})")
    return JointIdentification(fits, best_aic, best_bic, best_bic, params, data, notes)
