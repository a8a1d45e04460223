"""The diagnosis kernel's compile options."""
from ..._numba_cache import NUMBA_OPTIONS

#: The numba options of every compiled function (``@njit(**JIT)``): the package's one set.
JIT = NUMBA_OPTIONS
