"""What every stage of the diagnosis reads: the records' groups, the fit context, and the
one forward-difference Jacobian of the model's residuals."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..params.cell import CellParams
from ..params.schema import ParameterError
from . import stats
from .baseline import CHAIN, SHEET, moves, sheet_box, with_sheet
from .candidates import LinearFit
from .compare import RecordData
from .evaluate import Outcome, Runner, Task, all_ok
from .linear import Solver, Stack


class Group:
    """The records of one group (fit or holdout), how their residuals stack, and the
    measurement chain's columns (linear in the residuals)."""

    def __init__(self, data: list[RecordData], stack: Stack, chain: np.ndarray):
        self.data = data
        self.stack = stack
        self.chain = chain
        self._solvers: dict = {}

    @classmethod
    def of(cls, data: list[RecordData], sp: float, sf: float, nominal: list[Outcome]) -> Group:
        """The group of ``data`` with noise levels ``sp`` [m], ``sf`` [N]; the chain's
        columns from the nominal runs ``nominal``."""
        stack = Stack([d.point_frame for d in data], [d.record.has_wrench for d in data], sp, sf)
        stack.set_force_count(nominal)
        chain = stack.chain_columns(nominal) if data else np.zeros((0, len(CHAIN)))
        return cls(data, stack, chain)

    def z(self, outs: list[Outcome]) -> np.ndarray:
        return self.stack.vec(outs)

    def solver(self, A_sheet: np.ndarray) -> Solver:
        """The bounded fit on [A_sheet, chain columns]: its QR once per Jacobian (the
        baseline's, or a candidate's own, :func:`check.relinearise`)."""
        hit = self._solvers.get(id(A_sheet))
        if hit is None or hit[0] is not A_sheet:       # the array kept: its id stays its own
            hit = self._solvers[id(A_sheet)] = (A_sheet,
                                                Solver(np.hstack((A_sheet, self.chain))))
        return hit[1]

    def J(self, z: np.ndarray) -> float:
        return float(z @ z)

    def J_with_chain(self, z_raw: np.ndarray, u_chain: np.ndarray) -> float:
        """J of the raw residual ``z_raw`` with the measurement chain at ``u_chain`` (in
        tolerance units; linear in the residual): how a fit's chain carries to the holdout."""
        return self.J(z_raw + self.chain @ u_chain)

    def n_eff(self, z: np.ndarray) -> dict:
        """Each observable's effective sample size of the residual ``z`` (:mod:`stats`)."""
        st = self.stack
        prof = z[:st.n_p]
        frames = np.concatenate([d.point_frame + 100000 * i for i, d in enumerate(self.data)])
        out = {"profile": stats.n_eff_profile(prof, frames)}
        if st.n_f:
            out["tool force"] = stats.n_eff_force(z[st.n_p:].reshape(-1, 2))
        return out


@dataclass(frozen=True)
class FitContext:
    """What every stage reads: the fit and holdout records and their groups, the noise
    levels, and the runner that spends the simulations (one executor)."""

    fit_d: list[RecordData]
    hold_d: list[RecordData]
    G: Group
    H: Group | None
    run: Runner
    sp: float                       # m, profile noise
    sf: float                       # N, tool force noise
    sheet_lim: float = 1.0          # the sheet knobs' box times this (0: held as written)

    @property
    def data(self) -> list[RecordData]:
        return list(self.fit_d) + list(self.hold_d)

    @property
    def nf(self) -> int:
        return len(self.fit_d)

    @property
    def n_s(self) -> int:
        """Number of sheet knobs (their u come first in every fitted vector)."""
        return len(SHEET)

    @property
    def sheet_lo(self) -> np.ndarray:
        """The sheet knobs' lower bounds [tolerances] (:func:`.baseline.sheet_box`)."""
        return sheet_box(self.sheet_lim)[0]

    @property
    def sheet_hi(self) -> np.ndarray:
        """The sheet knobs' upper bounds [tolerances]."""
        return sheet_box(self.sheet_lim)[1]

    @property
    def chain_lim(self) -> np.ndarray:
        """The chain's bounds under the baseline: within tolerance (u in tolerances)."""
        return np.ones(len(CHAIN))

    @property
    def chain_free(self) -> np.ndarray:
        """The chain's bounds under the measurement-chain hypothesis: its fit limits."""
        return np.array([k.limit for k in CHAIN])

    def params(self, d: RecordData, u_s: np.ndarray) -> CellParams:
        """``d``'s written cell with the sheet knobs at ``u_s`` (tolerances); with the sheet
        held (``sheet_lim`` 0) the log knobs stay as written, offset and all."""
        return with_sheet(d.record.scenario, {k.name: float(v) for k, v in zip(SHEET, u_s)
                                              if moves(k, self.sheet_lim)})


@dataclass(frozen=True)
class Baseline:
    """The calibrated baseline (stage 2): the sheet knobs ``u_s`` and chain values ``u_c``
    (tolerances), its misfit on the fit and holdout records, its runs, its residual on the
    fit records (``z_raw`` chain uncorrected, ``z`` corrected), the misfit's parts and
    effective sample sizes, the sheet Jacobian ``A_sheet`` and the solvers the later stages
    fit with."""

    u_s: np.ndarray
    u_c: np.ndarray
    J: float
    J_h: float                      # nan without holdout records
    outs: list[Outcome]             # fit records, then holdout records
    z_raw: np.ndarray
    z: np.ndarray
    parts: dict
    n_eff: dict
    A_sheet: np.ndarray
    solver: Solver                  # [A_sheet, chain columns]
    chain_solver: Solver            # the chain's columns alone

    def chain_fit(self, z: np.ndarray, bound: np.ndarray):
        """Chain values for the fit records' residual ``z`` (sheet held), within +-``bound``:
        (u_chain, J, corrected z)."""
        u, J = self.chain_solver.solve(z, -bound, bound)
        return u, J, z + self.chain_solver.A @ u

    def linear(self, ctx: FitContext) -> LinearFit:
        """The linearised model at this baseline (knobs within their box, chain within
        tolerance), what the effects are fitted on."""
        lim = ctx.chain_lim
        return LinearFit(self.z_raw, self.solver, np.r_[ctx.sheet_lo - self.u_s, -lim],
                         np.r_[ctx.sheet_hi - self.u_s, lim], ctx.G.stack, self.n_eff, self.parts)


def forward_jacobian(ctx: FitContext, z_ref: np.ndarray, at: Callable[[int, float], list],
                     steps: Sequence[Sequence[float]],
                     invalid: Callable[[int], list],
                     announce: Callable[[int], None] | None = None) -> np.ndarray:
    """d z / d u of the fit records by forward differences, one simulation per knob and fit
    record: column j is (z(at(j, h)) - z_ref) / h for the first step h of ``steps[j]`` whose
    cells ``at(j, h)`` (one per fit record) are valid parameters; where none is,
    ``invalid(j)`` gives the cells to run (a zero column) or raises.  A knob whose runs fail
    has a zero column.  ``announce(n)``: told the number of simulations before they run."""
    tasks, used = [], []
    for j, hs in enumerate(steps):
        for h in hs:
            try:
                ps = at(j, h)
            except ParameterError:
                continue
            break
        else:
            ps, h = invalid(j), 0.0
        used.append(h)
        tasks += [Task(d, p) for d, p in zip(ctx.fit_d, ps)]
    if announce is not None:
        announce(len(tasks))
    outs = ctx.run(tasks)
    nf = ctx.nf
    cols = []
    for j, h in enumerate(used):
        o = outs[j * nf:(j + 1) * nf]
        ok = all_ok(o) and h != 0.0
        cols.append((ctx.G.z(o) - z_ref) / h if ok else np.zeros_like(z_ref))
    return np.column_stack(cols)


def inward_steps(u: np.ndarray, hi: np.ndarray, h: float) -> list[tuple[float]]:
    """One forward-difference step per knob for :func:`forward_jacobian`: ``h`` tolerances
    from ``u``, or ``-h`` where ``+h`` would pass the box's upper bound ``hi`` [tolerances]."""
    return [(h if u[j] + h <= hi[j] else -h,) for j in range(len(u))]
