"""The world kernel's numba options, packed-parameter indices and limits."""
from __future__ import annotations

from rheo_shaping._numba_cache import NUMBA_OPTIONS


#: The numba options of every compiled function (``@njit(**JIT)``): the package's one set.
JIT = NUMBA_OPTIONS

# ---------------------------------------------------------------- packed parameter indices
#: ``par`` vector of :func:`run_chain`
(I_GRAV, I_KC, I_CN, I_KT, I_MU_MOULD, I_MU_TOOL, I_AIR, I_CAKE_H, I_FILLET, I_RADIUS,
 I_TOOL_R, I_EI, I_PL_N, I_PL_REF, I_THIN, I_HARD, I_ADH, I_ADH_RANGE, I_LET_GO,
 I_SOFT_MOULD, I_SOFT_TOOL, I_SWEEP) = range(22)
N_PAR = 22
#: I_SOFT_MOULD, I_SOFT_TOOL: factors (>= 1; 0 read as 1) the cake and workplane's, and the
#: tool's, contact is softer by (stiffness / f, damping / sqrt f); I_SWEEP [s]: the hands let
#: go along the sheet (mass i's weight from |sweep| i / (N - 1), from the cake when > 0)
#: obstacles
CAKE, FLOOR, TOOL = 0, 1, 2
#: Newton solves per step at most, and the link-force mismatch [N] (law against its linear
#: model at the solution) below which a step is converged
MAX_NEWTON = 6
FORCE_TOL = 1e-4
