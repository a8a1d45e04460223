"""The online estimate of the batch's material: k1, c2 and the sheet's mass per length,
with their uncertainty, from the run's samples as they come.

The unknowns are the logarithms of the three knobs relative to the params file,
theta = (ln k1/k1_0, ln c2/c2_0, ln m/m_0), with a Gaussian prior theta ~ N(0, P^-1),
P = diag(1/s_k1^2, 1/s_c2^2, 1/s_m^2) (the batch-to-batch spread).  The model is the
core's own sheet (:func:`~rheo_shaping.sheet.simulation.run_scenario`, paper Sec. 4.1,
the three-element links of Eq. 1) driven by the executed tool poses from t = 0 to the newest
sample, from its settled sheet taken to first order about the estimate (:mod:`.settle`);
its observables (:mod:`.observe`) against the measured ones give the whitened residual
r(theta) = (h(theta) - y) / sigma.  Each refresh takes at most ``max_iterations``
Levenberg-Marquardt steps from the previous estimate,

    (J^T J + P + lambda diag(J^T J + P)) dtheta = -(J^T r + P theta),

J by forward differences (one run per knob), and the Laplace covariance of the
posterior,

    Sigma = s^2 (J^T J + P)^-1,   s^2 = max(1, chi^2 / dof)

(inflated by the reduced chi-square when the model explains the data worse than their
noise: a model-form gap widens the uncertainty instead of hiding in it).  A sample that
is no data (NaN, an absurd force) or a fit that diverges sets a bad status, latched: the
caller falls back to the fixed plan.  No ROS here.
"""
from __future__ import annotations

import enum
import math
import time
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from ..params.cell import CellParams
from ..params.validators import check_positive
from ..sheet.chain import ConvergenceError
from ..sheet.paths import PolylinePath
from ..sheet.simulation import RunResult, run_scenario
from .observe import NoiseModel, Sample, observation_matrix, predict
from .settle import LinearSettle, knobs_of, material_cell

#: The knobs estimated, in the order of theta.
KNOBS = ("k1", "c2", "mass_per_length")


class EstimateStatus(enum.Enum):
    """How far an :class:`Estimate` may be trusted."""

    PRIOR = "prior"            # no sample yet: the params file with the prior's spread
    OK = "ok"                  # a fit of the samples
    BAD_INPUT = "bad_input"    # a sample is no data (non-finite, absurd): latched
    DIVERGED = "diverged"      # the fit ran away or the model cannot explain the data: latched

    @property
    def usable(self) -> bool:
        """May a planner act on the estimate?"""
        return self in (EstimateStatus.PRIOR, EstimateStatus.OK)


@dataclass(frozen=True)
class EstimatorParams:
    """Settings of :class:`Estimator` (prior spreads relative [-], model sample spacing
    [s], force bound [N] as a multiple of F_break, divergence bounds)."""

    prior_k1: float = 0.3            # 1-sigma of ln k1 (batch-to-batch, issue 43: +-30 %)
    prior_c2: float = 0.3            # 1-sigma of ln c2
    prior_mass: float = 0.2          # 1-sigma of ln m
    model_spacing: float = 0.5       # s, tool poses kept for the model's path
    sample_spacing: float = 0.5      # s, samples kept for the fit (older: decimated)
    gap_spacing: float = 2.0         # s, gap samples kept for the fit (the dearest to predict)
    max_iterations: int = 1          # LM steps per refresh (warm-started: they add up)
    model_floor: float = 0.01        # 1-sigma of ln k1, ln c2, ln m the model's own step
    #                                  schedule leaves (a run on the decimated path against
    #                                  the planner's knots: 0.4-0.7 %, docs/closed-loop.md)
    fd_step: float = 0.01            # forward-difference step in theta
    max_force_ratio: float = 10.0    # |force| above this x F_break is a lying source
    max_log_ratio: float = math.log(4.0)   # |theta| beyond: diverged
    max_chi2: float = 400.0          # chi^2/dof beyond: the model cannot explain the data
    noise: NoiseModel = NoiseModel()
    #: the model's own error per observable (its form: the settled drape against a laid
    #: sheet, frictionless contact), added in quadrature to the noise in the weights
    model_error: NoiseModel = NoiseModel(force=0.01, tension=0.01, gap=1e-3)
    skip_before: float = 1.0         # s, samples before are not fitted (a sheet's release)
    max_step: float = 0.25           # largest change of any ln knob in one LM step

    def __post_init__(self) -> None:
        for name in ("prior_k1", "prior_c2", "prior_mass", "model_spacing", "sample_spacing",
                     "gap_spacing", "fd_step", "model_floor", "max_force_ratio",
                     "max_log_ratio", "max_chi2", "max_step"):
            check_positive(f"EstimatorParams.{name}", getattr(self, name))
        if not (math.isfinite(self.skip_before) and self.skip_before >= 0.0):
            raise ValueError(f"EstimatorParams.skip_before = {self.skip_before!r} s: expected "
                             "a finite number >= 0")
        if self.max_iterations < 1:
            raise ValueError(f"EstimatorParams.max_iterations = {self.max_iterations!r}: "
                             "expected an integer >= 1")

    def sigmas(self) -> np.ndarray:
        """(4,) weight of each observable: noise and model error in quadrature."""
        return np.hypot(self.noise.sigmas(), self.model_error.sigmas())

    def prior_precision(self) -> np.ndarray:
        """P (3, 3), the prior's precision of theta."""
        return np.diag(1.0 / np.array([self.prior_k1, self.prior_c2, self.prior_mass]) ** 2)


@dataclass(frozen=True)
class Estimate:
    """The material as the samples up to ``t`` [s] say: k1 [N/m], c2 [N s/m], mass per
    length [kg/m], the covariance of their logarithms ``cov`` (3x3, order
    :data:`KNOBS`), chi^2/dof of the fit, samples and LM steps used, the refresh's cost
    [s of CPU on this process], status and message (why, for a bad one)."""

    t: float
    status: EstimateStatus
    message: str
    k1: float
    c2: float
    mass_per_length: float
    cov: tuple[tuple[float, ...], ...]
    chi2_dof: float = math.nan
    n_samples: int = 0
    iterations: int = 0
    cost_s: float = 0.0

    @property
    def theta(self) -> np.ndarray:
        """(3,) the values of :data:`KNOBS`."""
        return np.array([self.k1, self.c2, self.mass_per_length])

    @property
    def sigma_rel(self) -> np.ndarray:
        """(3,) 1-sigma of ln k1, ln c2, ln m (relative uncertainty)."""
        return np.sqrt(np.diag(np.asarray(self.cov)))

    def knobs(self, z: Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        """(3,) k1, c2, m at ``z`` sigmas of each logarithm from the estimate."""
        return self.theta * np.exp(np.asarray(z, float) * self.sigma_rel)

    def cell(self, base: CellParams, z: Sequence[float] = (0.0, 0.0, 0.0)) -> CellParams:
        """``base`` with this estimate's material (``z`` sigmas off, see :meth:`knobs`)."""
        return material_cell(base, self.knobs(z))

    def as_dict(self) -> dict:
        """Plain numbers (SI units) for logs and ``/shaping/estimate``."""
        return {"t": self.t, "status": self.status.value, "message": self.message,
                "k1": self.k1, "c2": self.c2, "mass_per_length": self.mass_per_length,
                "sigma_rel": self.sigma_rel.tolist(), "chi2_dof": self.chi2_dof,
                "n_samples": self.n_samples, "iterations": self.iterations,
                "cost_s": self.cost_s}


class Estimator:
    """Online estimate of :data:`KNOBS` for the cell ``cell`` (the params file's)."""

    def __init__(self, cell: CellParams, params: EstimatorParams = EstimatorParams()):
        self.cell = cell
        self.params = params
        self.nominal = knobs_of(cell)
        self.samples: list[Sample] = []
        self.theta = np.zeros(3)
        # the runs' settled sheets, to first order about the estimate (settle.py)
        self.settle = LinearSettle.about(cell)
        self._cov = np.linalg.inv(params.prior_precision())
        self.bad = ""                       # latched reason of a bad status
        self._t_gap = -math.inf             # time of the newest gap kept
        self.bad_status = EstimateStatus.OK
        self.estimate = self._make(0.0, EstimateStatus.PRIOR, "the params file's material "
                                   "with the prior's spread (no sample yet)", math.nan, 0, 0.0)

    # -- input --------------------------------------------------------------------------
    def update(self, samples: Sequence[Sample]) -> Estimate:
        """Take the new ``samples`` (process time increasing) and refresh the estimate."""
        wall = time.process_time()
        if not self.bad:
            self._take(samples)
        if not self.bad:
            self._refit()
        if self.bad:
            est = self._make(self._t_last(), self.bad_status, self.bad, math.nan, 0,
                             time.process_time() - wall)
        else:
            est = replace(self.estimate, cost_s=time.process_time() - wall)
        self.estimate = est
        return est

    def _t_last(self) -> float:
        return self.samples[-1].t if self.samples else 0.0

    def _take(self, samples: Sequence[Sample]) -> None:
        f_max = self.params.max_force_ratio * self.cell.material.F_break
        for s in samples:
            why = s.bad_value()
            if not why:
                big = max(abs(s.wrench[0]), abs(s.wrench[1]), abs(s.contact_tension or 0.0))
                if big > f_max:
                    why = (f"force {big:.4g} N at t = {s.t:.3f} s: expected at most "
                           f"max_force_ratio x F_break = {f_max:.4g} N (a lying source)")
            if not why and self.samples and s.t <= self.samples[-1].t:
                why = (f"sample time {s.t!r} s: expected after the previous sample's "
                       f"{self.samples[-1].t!r} s")
            if why:
                self.bad, self.bad_status = why, EstimateStatus.BAD_INPUT
                return
            if not self.samples or s.t >= self.samples[-1].t + self.params.sample_spacing - 1e-9:
                if s.gap is not None and s.t < self._t_gap + self.params.gap_spacing - 1e-9:
                    s = replace(s, gap=None)
                elif s.gap is not None:
                    self._t_gap = s.t
                self.samples.append(s)       # closer ones are left out (decimation)

    # -- the fit ------------------------------------------------------------------------
    def _path(self) -> PolylinePath:
        t = np.array([s.t for s in self.samples])
        xz = np.array([s.tool for s in self.samples], dtype=float)
        keep = np.zeros(t.size, dtype=bool)
        keep[[0, -1]] = True
        grid = np.floor(t / self.params.model_spacing)
        keep[1:] |= grid[1:] != grid[:-1]
        if t[0] > 0.0:                     # the tool held its first pose from t = 0
            return PolylinePath(np.r_[0.0, t[keep]], np.vstack((xz[0], xz[keep])))
        return PolylinePath(t[keep], xz[keep])

    def model_run(self, theta: np.ndarray) -> RunResult:
        """The sheet with material ``nominal * exp(theta)`` on the executed tool poses."""
        t_end = self.samples[-1].t
        cell = material_cell(self.cell, self.nominal * np.exp(theta))
        if cell.movement.process_time < t_end:
            cell = replace(cell, movement=replace(cell.movement, process_time=t_end))
        return run_scenario(cell, self._path(), t_end=t_end, start=self.settle.state(theta))

    def residual(self, theta: np.ndarray, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whitened residual of the measured observables (NaN-free, flat)."""
        run = self.model_run(theta)
        h = predict(run, t, ~np.isnan(y[:, 3]))
        r = (h - y) / self.params.sigmas()
        r = r[~np.isnan(y)]
        if not np.all(np.isfinite(r)):
            raise FloatingPointError("the model's observables are not finite")
        return r

    def _objective(self, theta: np.ndarray, t: np.ndarray, y: np.ndarray
                   ) -> tuple[float, np.ndarray]:
        r = self.residual(theta, t, y)
        P = self.params.prior_precision()
        return float(r @ r + theta @ P @ theta), r

    def _jacobian(self, theta: np.ndarray, r0: np.ndarray, t: np.ndarray,
                  y: np.ndarray) -> np.ndarray:
        h = self.params.fd_step
        cols = []
        for i in range(3):
            th = theta.copy()
            th[i] += h
            cols.append((self.residual(th, t, y) - r0) / h)
        return np.stack(cols, axis=1)

    def _refit(self) -> None:
        if not self.samples:
            return
        t, y = observation_matrix(self.samples)
        fitted = t >= self.params.skip_before
        if not fitted.any():
            return
        t, y = t[fitted], y[fitted]
        P = self.params.prior_precision()
        theta = self.theta.copy()
        lam = 1e-3
        try:
            self.settle.recentre(theta)
            cost, r = self._objective(theta, t, y)
            steps = 0
            for _ in range(self.params.max_iterations):
                J = self._jacobian(theta, r, t, y)   # also the covariance's (at the step's start)
                A = J.T @ J + P
                g = J.T @ r + P @ theta
                steps += 1
                for _ in range(3):           # at most three trials of lambda per step
                    step = np.linalg.solve(A + lam * np.diag(np.diag(A)), -g)
                    longest = max(float(np.max(np.abs(step))), 1e-300)
                    step *= min(1.0, self.params.max_step / longest)
                    new_cost, new_r = self._objective(theta + step, t, y)
                    if new_cost <= cost:
                        theta, cost, r = theta + step, new_cost, new_r
                        lam = max(lam / 10.0, 1e-7)
                        break
                    lam *= 10.0
                if float(np.max(np.abs(step))) < 1e-3:
                    break
        except (ConvergenceError, FloatingPointError, ValueError, np.linalg.LinAlgError) as exc:
            self.bad, self.bad_status = (f"the fit diverged at t = {t[-1]:.2f} s: "
                                         f"{type(exc).__name__}: {exc}"), EstimateStatus.DIVERGED
            return
        dof = max(r.size - 3, 1)
        chi2 = float(r @ r) / dof
        if np.max(np.abs(theta)) > self.params.max_log_ratio or chi2 > self.params.max_chi2:
            worst = int(np.argmax(np.abs(theta)))
            self.bad, self.bad_status = (
                f"the fit diverged at t = {t[-1]:.2f} s: {KNOBS[worst]} x "
                f"{math.exp(theta[worst]):.3g} of the params file, chi^2/dof = {chi2:.3g} "
                f"(expected within x{math.exp(self.params.max_log_ratio):.3g} and chi^2/dof <= "
                f"{self.params.max_chi2:g})"), EstimateStatus.DIVERGED
            return
        self.theta = theta
        floor = np.eye(3) * self.params.model_floor ** 2
        self._cov = np.linalg.inv(J.T @ J + P) * max(1.0, chi2) + floor
        self.estimate = self._make(float(t[-1]), EstimateStatus.OK,
                                   f"fit of {t.size} samples, {steps} LM steps", chi2, steps, 0.0)

    def _make(self, t: float, status: EstimateStatus, message: str, chi2: float,
              iterations: int, cost: float) -> Estimate:
        k1, c2, m = self.nominal * np.exp(self.theta)
        return Estimate(t=t, status=status, message=message, k1=float(k1), c2=float(c2),
                        mass_per_length=float(m),
                        cov=tuple(tuple(float(v) for v in row) for row in self._cov),
                        chi2_dof=chi2, n_samples=len(self.samples), iterations=iterations,
                        cost_s=cost)
