"""Joint nonlinear least-squares fit of one material model to all the data.

Beyond the paper (Sec. 3.4 identifies the constants one at a time).  One
model -- Maxwell, three-element or Burgers -- is fitted at once to

* tensile curves up to crack initiation
(:func:`rheo_shaping.identification.paper_method.prepare_tensile`),
  each with its own load-cell offset as a nuisance parameter: the model force
  is 0 at rest (``t <= 0``) and Eq. 5 (Burgers: its closed form) during the
  pull, plus the offset;
* creep residuals (Table 1 type), ``x = F t1/c2`` (Eq. 9);
* creep curves, through the exact force-driven response
  (:func:`rheo_shaping.material.response.force_response`).

Noise model: tensile samples have standard deviation ``sigma_T * (noise_rel
* |F| + noise_abs)`` (the shape is assumed, default 1 % of F plus 1 mN; the
scale ``sigma_T`` is estimated); creep residuals and creep curves each have
their own constant standard deviation, estimated from their own spread.
The fit maximises the Gaussian likelihood: it alternates a weighted least
squares (``scipy.optimize.least_squares``, bounds ``k1, c2 > 0``,
``c1, j2 >= 0``) with the update of the three scales.

Parameters, on the 0.1 m specimen: Maxwell ``(k1, c2)`` (c1 = 0),
three-element ``(k1, c1, c2)``, Burgers ``(k1, c1, c2, j2 = 1/k2)``; the
models are nested (``j2 = 0`` is the three-element unit, ``c1 = 0`` Maxwell),
which is what lets :mod:`rheo_shaping.identification.model_choice` compare them.

Standard errors come from the Jacobian of the whitened residuals at the
optimum (each block divided by its own estimated scale, with the degrees of
freedom that block spends): ``cov = (J^T J)^-1``.  Directions of parameter
space the data do not see (singular values below ``1e-7`` of the largest)
make the parameters they involve *not identifiable*: their standard errors
are ``None``.  Intervals are ``value +- t * se`` (Student t with the residual
degrees of freedom), clipped at the bounds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..material.burgers import Burgers, burgers_tensile_force
from ..material.closed_forms import tensile_force
from .estimates import Estimate, symmetric
from .paper_method import PreparedCurve, c2_from_creep, eq13_points
from ..material.three_element import SPECIMEN_LENGTH_M, ThreeElement
from .material_data import CreepCurve, CreepResiduals
from ..material.response import force_response

MODELS = ("maxwell", "three-element", "burgers")
PARAMETERS = {"maxwell": ("k1", "c2"), "three-element": ("k1", "c1", "c2"),
              "burgers": ("k1", "c1", "c2", "j2")}
UNITS = {"k1": "N/m", "c1": "N s/m", "c2": "N s/m", "j2": "m/N", "k2": "N/m", "offset": "N"}
_SINGULAR_RTOL = 1e-7


@dataclass(frozen=True, eq=False)
class FitData:
    """The data of a joint fit and the assumed shape of the tensile noise."""

    curves: list[PreparedCurve] = field(default_factory=list)
    residuals: CreepResiduals | None = None
    creep_curves: list[CreepCurve] = field(default_factory=list)
    noise_rel: float = 0.01
    noise_abs: float = 1e-3

    @property
    def has_shape(self) -> bool:
        """True when some data depend on more than c2 (tensile or creep curves)."""
        return bool(self.curves) or bool(self.creep_curves)


@dataclass(frozen=True, eq=False)
class Block:
    """One group of residuals with its own noise scale: what was fitted and how well."""

    name: str
    n: int
    sigma: float                  # estimated scale (ML: RSS/n) of the whitened residuals
    dof_used: int                 # rank of this block's Jacobian
    rss: float                    # sum of squared shape-weighted residuals


@dataclass(frozen=True, eq=False)
class ModelFit:
    """A fitted model: constants on the 0.1 m specimen, offsets, likelihood.

    ``params`` maps k1, c1, c2 (and k2, j2 for Burgers) to :class:`Estimate`;
    ``offsets``: one per tensile curve [N]; ``loglik``: maximised Gaussian
    log-likelihood; ``k``: free parameters (constants, offsets, noise scales);
    ``n``: data points; ``aic = -2 loglik + 2k``, ``bic = -2 loglik + k ln n``.
    """

    model: str
    params: dict[str, Estimate]
    offsets: list[Estimate]
    loglik: float
    k: int
    n: int
    aic: float
    bic: float
    blocks: list[Block]
    theta: np.ndarray
    success: bool
    message: str

    def material(self, length: float = SPECIMEN_LENGTH_M) -> "ThreeElement | Burgers":
        """The fitted unit over ``length`` [m]."""
        return _material(self.model, dict(zip(PARAMETERS[self.model], self.theta)), length)


# ----------------------------------------------------------- model curves
def _material(model: str, p: dict, length: float) -> "ThreeElement | Burgers":
    m: ThreeElement | Burgers
    if model == "maxwell":
        m = ThreeElement(p["k1"], 0.0, p["c2"], SPECIMEN_LENGTH_M)
    elif model == "three-element":
        m = ThreeElement(p["k1"], p["c1"], p["c2"], SPECIMEN_LENGTH_M)
    else:
        j2 = p["j2"]
        m = Burgers(p["k1"], p["c1"], p["c2"], math.inf if j2 ==
                    0.0 else 1.0 / j2, SPECIMEN_LENGTH_M)
    return m if length == SPECIMEN_LENGTH_M else m.scaled(length)


def model_tensile_force(m: "ThreeElement | Burgers", t: np.ndarray, speed: float) -> np.ndarray:
    """Model force [N] of a tensile test: 0 at rest (t <= 0), Eq. 5 / Burgers during the pull."""
    F = np.zeros_like(t, dtype=float)
    pull = t > 0.0
    if isinstance(m, Burgers):
        F[pull] = burgers_tensile_force(m, t[pull], speed)
    else:
        F[pull] = tensile_force(m, t[pull], speed)
    return F


def _shape_weights(data: FitData) -> list[np.ndarray]:
    return [data.noise_rel * np.abs(c.zeroed_force) + data.noise_abs for c in data.curves]


class _Problem:
    """Residuals of one model on one data set, in scaled parameters u = theta/scale."""

    def __init__(self, model: str, data: FitData, scale: np.ndarray):
        self.model, self.data, self.scale = model, data, scale
        self.names = PARAMETERS[model]
        self.np_ = len(self.names)
        self.weights = _shape_weights(data)
        self.block_names = []
        self.block_sizes = []
        if data.curves:
            self.block_names.append("tensile")
            self.block_sizes.append(sum(c.t.size for c in data.curves))
        if data.residuals is not None:
            self.block_names.append("creep residuals")
            self.block_sizes.append(len(data.residuals))
        if data.creep_curves:
            self.block_names.append("creep curves")
            self.block_sizes.append(sum(c.t.size for c in data.creep_curves))

    def raw(self, theta: np.ndarray) -> list[np.ndarray]:
        """Shape-weighted (not yet scale-divided) residuals per block."""
        p = dict(zip(self.names, theta[: self.np_]))
        out = []
        d = self.data
        if d.curves:
            r = []
            for i, (c, w) in enumerate(zip(d.curves, self.weights)):
                m = _material(self.model, p, c.length)
                F = model_tensile_force(m, c.t, c.speed) + theta[self.np_ + i]
                r.append((c.force - F) / w)
            out.append(np.concatenate(r))
        if d.residuals is not None:
            cr = d.residuals
            c2 = p["c2"] * SPECIMEN_LENGTH_M / cr.length
            out.append(cr.residual - cr.force * cr.t1 / c2)
        if d.creep_curves:
            r = []
            for cc in d.creep_curves:
                m = _material(self.model, p, cc.length)
                r.append(cc.elongation - force_response(m, cc.t, cc.force, cc.hold).elongation)
            out.append(np.concatenate(r))
        return out

    def whitened(self, u: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        return np.concatenate([r / s for r, s in zip(self.raw(u * self.scale), sigma)])


# ------------------------------------------------------------- starting
def starting_values(data: FitData) -> dict:
    """Rough constants to start from: c2 from creep (Eq. 10) or the curves, k1 from Eq. 12-13."""
    c2 = None
    if data.residuals is not None:
        c2 = c2_from_creep(data.residuals).value
    if c2 is None and data.curves:
        c2 = max(float(np.max(c.zeroed_force)) / c.speed * c.length / SPECIMEN_LENGTH_M
                 for c in data.curves) * 1.25
    if c2 is None and data.creep_curves:
        c = data.creep_curves[0]
        impulse = float(np.sum(c.force[:-1] * np.diff(c.t)))
        slope = max(float(c.elongation[-1]), 1e-6)
        c2 = impulse / slope
    c2 = c2 if c2 and np.isfinite(c2) and c2 > 0 else 1e3
    k1 = 0.05 * c2
    if data.curves:
        X, Y = eq13_points(data.curves, 0.0, c2)
        if X.size >= 3 and float(X @ X) > 0:
            b = -float(X @ Y) / float(X @ X)
            if b > 0:
                k1 = b * c2
    offsets = [c.offset if c.offset is not None else float(c.force[0]) for c in data.curves]
    return {"k1": k1, "c1": 0.0, "c2": c2, "j2": 0.0, "offsets": offsets}


def _initial_sigma(problem: _Problem, data: FitData) -> np.ndarray:
    s = []
    for name in problem.block_names:
        if name == "tensile":
            s.append(1.0)
        elif name == "creep residuals":
            assert data.residuals is not None        # the block exists for them (_Problem)
            r = data.residuals.residual
            s.append(float(np.std(r, ddof=1)) if r.size >
                     1 and np.std(r) > 0 else 0.03 * float(np.mean(r)))
        else:
            s.append(0.01 * max(float(np.max(np.abs(c.elongation)))
                     for c in data.creep_curves) + 1e-12)
    return np.array(s)


def _starts(model: str, base: dict, previous: "ModelFit | None") -> list[dict]:
    k1, c2 = base["k1"], base["c2"]
    starts = []
    if previous is not None:
        p = dict(zip(PARAMETERS[previous.model], previous.theta))
        p.setdefault("c1", 0.0)
        p.setdefault("j2", 0.0)
        p["offsets"] = list(previous.theta[len(PARAMETERS[previous.model]):])
        starts.append(p)
        k1, c2 = p["k1"], p["c2"]
    offs = base["offsets"] if previous is None else starts[0]["offsets"]
    if model == "maxwell":
        starts += [dict(k1=k1, c1=0.0, c2=c2, j2=0.0, offsets=offs),
                   dict(k1=k1, c1=0.0, c2=1.5 * c2, j2=0.0, offsets=offs)]
    elif model == "three-element":
        starts += [dict(k1=k1, c1=f * c2, c2=c2, j2=0.0, offsets=offs) for f in (0.05, 0.3, 1.0)]
    else:
        c1 = starts[0]["c1"] if starts else 0.0
        starts += [dict(k1=k1, c1=max(c1, 0.2 * c2), c2=c2, j2=f / k1, offsets=offs)
                   for f in (0.3, 1.0, 3.0)]
    return starts


# ------------------------------------------------------------------ fit
def fit_model(model: str, data: FitData, previous: "ModelFit | None" = None,
              max_rounds: int = 10) -> ModelFit:
    """Fit ``model`` to ``data`` (see the module doc); ``previous``: a nested model's fit to start
    from."""
    if model not in MODELS:
        raise ValueError(f"model = {model!r}: expected one of {', '.join(MODELS)}")
    if data.residuals is None and not data.has_shape:
        raise ValueError("no data to fit: give tensile curves, creep residuals or creep curves")
    base = starting_values(data)
    names = PARAMETERS[model]
    nc = len(data.curves)
    scale = np.array([{"k1": base["k1"], "c1": base["c2"], "c2": base["c2"],
                       "j2": 1.0 / base["k1"]}[n]
                      for n in names] + [0.01] * nc)
    lower = np.array([1e-9 if n in ("k1", "c2") else 0.0 for n in names] + [-np.inf] * nc)
    upper = np.full(lower.shape, np.inf)
    prob = _Problem(model, data, scale)
    sigma = _initial_sigma(prob, data)

    def to_u(s: dict) -> np.ndarray:
        th = np.array([s[n] for n in names] + list(s["offsets"]), dtype=float)
        return np.clip(th / scale, lower + 1e-12 * (lower > 0), upper)

    def solve(u0: np.ndarray, sig: np.ndarray):
        return least_squares(prob.whitened, u0, args=(sig,), bounds=(lower, upper), method="trf",
                             x_scale=1.0, ftol=1e-12, xtol=1e-12, gtol=1e-12,
                             max_nfev=400 * (len(u0) + 1))

    best = None
    for s in _starts(model, base, previous):
        try:
            res = solve(to_u(s), sigma)
        except ValueError:
            continue
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        raise RuntimeError(f"{model}: no start converged")
    sizes = np.array(prob.block_sizes)
    for _ in range(max_rounds):
        raw = prob.raw(best.x * scale)
        new = np.array([math.sqrt(max(float(r @ r) / r.size, 1e-300)) for r in raw])
        change = float(np.max(np.abs(new / sigma - 1.0)))
        sigma = new
        best = solve(best.x, sigma)
        if change < 1e-6:
            break
    return _summarise(model, data, prob, best, sigma, sizes, scale, lower)


def _summarise(model, data, prob, res, sigma_ml, sizes, scale, lower) -> ModelFit:
    names = PARAMETERS[model]
    theta = res.x * scale
    raw = prob.raw(theta)
    N = int(sizes.sum())
    # Jacobian of the raw residuals w.r.t. u (res.jac is of the residuals divided by sigma_ml)
    row_sig = np.repeat(sigma_ml, sizes)
    J_raw = res.jac * row_sig[:, None]
    # per-block degrees of freedom spent, and unbiased scales
    blocks, sig_final = [], []
    start = 0
    for name, n, r, s in zip(prob.block_names, sizes, raw, sigma_ml):
        Jb = J_raw[start:start + n]
        start += n
        sv = np.linalg.svd(Jb, compute_uv=False) if Jb.size else np.zeros(1)
        rank = int(np.sum(sv > _SINGULAR_RTOL * sv[0])) if sv.size and sv[0] > 0 else 0
        rss = float(r @ r)
        sig_final.append(math.sqrt(rss / max(n - rank, 1)))
        blocks.append(Block(name, int(n), float(s), rank, rss))
    Jw = J_raw / np.repeat(sig_final, sizes)[:, None]
    U, S, Vt = np.linalg.svd(Jw, full_matrices=False)
    keep = S > _SINGULAR_RTOL * S[0] if S.size and S[0] > 0 else np.zeros(S.shape, bool)
    rank = int(keep.sum())
    null = Vt[~keep]
    unident = (np.abs(null) > 1e-3).any(axis=0) if null.size else np.zeros(theta.size, bool)
    cov_u = (Vt[keep].T / S[keep] ** 2) @ Vt[keep]
    se = np.sqrt(np.maximum(np.diag(cov_u), 0.0)) * scale
    dof = max(N - rank, 1)
    params: dict[str, Estimate] = {}
    value = {n: float(v) for n, v in zip(names, theta)}
    for i, n in enumerate(names):
        if unident[i]:
            params[n] = Estimate(value[n], None, None, UNITS[n],
                                 "not identifiable from these data")
        else:
            params[n] = symmetric(value[n], float(se[i]), UNITS[n],
                                  dof, f"joint fit ({model})", lower=0.0)
    if model == "burgers" and value["j2"] * value["k1"] < 1e-6:
        # 1/k2 on its bound: the Burgers fit is the three-element fit, and at
        # j2 = 0 a small series compliance looks like a change of k1 and c1
        params["j2"] = Estimate(0.0, None, (0.0, None), UNITS["j2"],
                                "at its bound 0: the data show no series spring")
        for n in ("k1", "c1"):
            if params[n].se is None:
                params[n] = Estimate(params[n].value, None, None, UNITS[n],
                                     "not separable from 1/k2 at its bound 0 (see the "
                                     "three-element fit)")
    if "c1" not in params:
        params["c1"] = Estimate(0.0, None, None, UNITS["c1"], "fixed at 0 by the Maxwell model")
    if model == "burgers":
        params["k2"] = _k2_from_j2(params["j2"])
    offsets = []
    for i in range(len(names), theta.size):
        offsets.append(Estimate(float(theta[i]), None, None, "N", "not identifiable") if unident[i]
                       else symmetric(float(theta[i]), float(se[i]), "N", dof, "load-cell offset"))
    # Gaussian log-likelihood at the ML scales (constant terms included)
    loglik = 0.0
    for b in blocks:
        loglik -= 0.5 * b.n * (math.log(2 * math.pi * max(b.rss / b.n, 1e-300)) + 1.0)
    loglik -= float(sum(np.sum(np.log(w)) for w in prob.weights))   # tensile weights (data-only)
    k = theta.size + len(blocks)
    return ModelFit(model, params, offsets, loglik, k, N, -2 * loglik + 2 * k,
                    -2 * loglik + k * math.log(N),
                    blocks, theta, bool(res.success), str(res.message))


def _k2_from_j2(j2: Estimate) -> Estimate:
    """k2 = 1/j2 [N/m]: se by the delta method, the interval mapped (j2 = 0 means k2 = inf)."""
    v = j2.value
    if v is None or v <= 0.0:
        hi_j = None if j2.ci95 is None else j2.ci95[1]
        lo_k = None if not hi_j else 1.0 / hi_j
        return Estimate(math.inf, None, (lo_k, None), "N/m", "j2 = 0: no series spring "
                                                             "(three-element)")
    se = None if j2.se is None else j2.se / v ** 2
    ci = None
    if j2.ci95 is not None:
        lo_j, hi_j = j2.ci95
        ci = (1.0 / hi_j if hi_j else None, 1.0 / lo_j if lo_j and lo_j > 0 else None)
    return Estimate(1.0 / v, se, ci, "N/m", j2.note)
