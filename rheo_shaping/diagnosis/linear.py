"""Residual vectors of a group of records and the bounded linearised fits on them.

:class:`Stack` turns per-record :class:`~.evaluate.Outcome` residuals into one
weighted vector z whose squared norm is the balanced misfit J (see
:mod:`stats`), and builds the measurement chain's columns (linear in the
residuals).  :class:`Solver` minimises |z + A u|^2 over box-bounded u with
the columns' QR factor computed once, so hundreds of candidate fits cost
milliseconds, not simulations.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .baseline import CHAIN
from .evaluate import Outcome


@dataclass
class Stack:
    """How the records of a group stack into one weighted residual vector."""

    frames: list[np.ndarray]       # per record, point_frame
    has_force: list[bool]
    sigma_p: float                 # m
    sigma_f: float                 # N
    n_p: int = 0
    n_f: int = 0

    def __post_init__(self) -> None:
        self.n_p = int(sum(f.size for f in self.frames))

    def set_force_count(self, outcomes: list[Outcome]) -> None:
        self.n_f = int(sum(o.array("force").shape[0]
                           for o, h in zip(outcomes, self.has_force) if h))

    @property
    def w_p(self) -> float:
        half = 2.0 if self.n_f else 1.0
        return 1.0 / (self.sigma_p * math.sqrt(half * self.n_p))

    @property
    def w_f(self) -> float:
        return 1.0 / (self.sigma_f * math.sqrt(2.0 * 2.0 * self.n_f)) if self.n_f else 0.0

    def vec(self, outcomes: list[Outcome]) -> np.ndarray:
        """z: weighted profile residuals of every record, then their force residuals (x, z)."""
        prof = [o.array("profile") * self.w_p for o in outcomes]
        force = [o.array("force").reshape(-1) * self.w_f
                 for o, h in zip(outcomes, self.has_force) if h]
        return np.concatenate(prof + force)

    def masks(self) -> dict:
        n = self.n_p + 2 * self.n_f
        m_p = np.zeros(n, bool)
        m_p[:self.n_p] = True
        out = {"profile": m_p}
        if self.n_f:
            out["tool force"] = ~m_p
        return out

    def J_parts(self, z: np.ndarray) -> dict:
        """Per-observable misfit (1: within noise) of weighted residual ``z``."""
        out = {}
        for o, m in self.masks().items():
            s = float(np.sum(z[m] ** 2))
            out[o] = s * (2.0 if self.n_f else 1.0)
        return out

    def chain_columns(self, outcomes: list[Outcome]) -> np.ndarray:
        """d z / d u for each CHAIN knob (u in tolerances), from the model run of ``outcomes``."""
        tol = {k.name: k.tolerance for k in CHAIN}
        cols = np.zeros((self.n_p + 2 * self.n_f, len(CHAIN)))
        normal = np.concatenate([o.normal for o in outcomes])
        cols[:self.n_p, 0] = -normal[:, 0] * self.w_p * tol["vision.dx"]
        cols[:self.n_p, 1] = -normal[:, 1] * self.w_p * tol["vision.dz"]
        if self.n_f:
            mf = np.concatenate([o.model_force for o, h in zip(outcomes, self.has_force) if h])
            md = np.concatenate([o.model_dforce for o, h in zip(outcomes, self.has_force) if h])
            f = slice(self.n_p, None)
            bx = np.zeros_like(mf)
            bx[:, 0] = -1.0
            bz = np.zeros_like(mf)
            bz[:, 1] = -1.0
            cols[f, 2] = bx.reshape(-1) * self.w_f * tol["load_cell.bias_x"]
            cols[f, 3] = bz.reshape(-1) * self.w_f * tol["load_cell.bias_z"]
            cols[f, 4] = -mf.reshape(-1) * self.w_f * tol["load_cell.gain"]
            cols[f, 5] = md.reshape(-1) * self.w_f * tol["load_cell.lag"]
        return cols


class Solver:
    """min |z + A u|^2 with lo <= u <= hi, A fixed (QR once), z varying."""

    def __init__(self, A: np.ndarray):
        self.A = A
        self.Q, self.R = np.linalg.qr(A, mode="reduced")

    def solve(self, z: np.ndarray, lo: np.ndarray, hi: np.ndarray, extra: np.ndarray | None = None,
              extra_bounds=None):
        """(u, J) of the bounded fit; ``extra`` (n, m) columns are fitted too (their u last)."""
        if extra is None or extra.shape[1] == 0:
            qz = self.Q.T @ z
            rest = float(z @ z - qz @ qz)
            if self.R.shape[1] == 0:
                return np.zeros(0), float(z @ z)
            u = _bounded(self.R, -qz, lo, hi)
            return u, max(rest, 0.0) + float(np.sum((self.R @ u + qz) ** 2))
        # extra columns: project them out of the fixed factor (small dense problem)
        qe = self.Q.T @ extra
        e_perp = extra - self.Q @ qe
        q2, r2 = np.linalg.qr(e_perp, mode="reduced")
        qz = self.Q.T @ z
        z_perp = z - self.Q @ qz
        q2z = q2.T @ z_perp
        rest = float(z_perp @ z_perp - q2z @ q2z)
        k, m = self.R.shape[1], extra.shape[1]
        top = np.hstack((self.R, qe))
        bot = np.hstack((np.zeros((m, k)), r2))
        M = np.vstack((top, bot))
        rhs = -np.concatenate((qz, q2z))
        elo, ehi = extra_bounds
        u = _bounded(M, rhs, np.r_[lo, elo], np.r_[hi, ehi])
        return u, max(rest, 0.0) + float(np.sum((M @ u - rhs) ** 2))

    def residual(self, z: np.ndarray, u: np.ndarray,
                 extra: np.ndarray | None = None) -> np.ndarray:
        out = z + self.A @ u[:self.A.shape[1]]
        if extra is not None and extra.shape[1]:
            out = out + extra @ u[self.A.shape[1]:]
        return out


def _bounded(M: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """argmin |M x - b| over lo <= x <= hi (a bound pair lo == hi holds that x fixed)."""
    from scipy.optimize import lsq_linear
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    free = hi > lo + 1e-12
    x = np.where(free, 0.0, lo)
    if not free.any():
        return x
    rhs = b - M[:, ~free] @ x[~free]
    sol = lsq_linear(M[:, free], rhs, bounds=(lo[free], hi[free]), method="bvls")
    x[free] = sol.x
    return x
