"""Constants of the compiled step: obstacle kinds, status codes, counters, the packed
float parameters, numba options."""
from __future__ import annotations

from ..._numba_cache import NUMBA_OPTIONS


#: Obstacle kinds of the array description (``Shape.kernel_description``).
CAKE_KIND, PLANE_KIND, POLYGON_KIND = 0, 1, 2

#: Status codes of a step.
OK, NOT_CONVERGED, NOT_SPD = 0, 1, 2

#: Counters returned in ``stats``: Newton iterations, energy evaluations, banded solves,
#: sub-steps taken (> 1: half-step retries), failed minimisations.
ST_NEWTON, ST_EVAL, ST_SOLVE, ST_SUBSTEPS, ST_FAILED = 0, 1, 2, 3, 4

# indices into the packed float parameters
(P_RADIUS, P_GRAVITY, P_KC, P_TOL, P_THIN, P_PLN, P_PLREF, P_EPS, P_SHX, P_SHZ,
 P_TOPX, P_TOPZ, P_BOTX, P_BOTZ, P_BENDING, P_SIZE) = range(16)

TINY = 1e-300


#: The numba options of every compiled function (``@njit(**JIT)``): the package's one set.
JIT = NUMBA_OPTIONS
