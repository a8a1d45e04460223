"""OpenBLAS on one thread while the diagnosis's worker processes simulate (the stages' own
linear algebra is small; OpenBLAS's threads would spin against the workers for the cores).
Imports nothing of the package."""
from __future__ import annotations

import contextlib
from typing import Iterator


#: OpenBLAS's calls that set and read its thread count, by the names its builds export
#: (plain, 64-bit integer, numpy's and scipy's wheels).
_BLAS_THREADS = tuple((f"{p}openblas_set_num_threads{s}", f"{p}openblas_get_num_threads{s}")
                      for p in ("", "scipy_") for s in ("", "64_"))


def _blas_thread_calls() -> list:
    """(set, get) of every OpenBLAS loaded in this process (Linux: from /proc/self/maps;
    elsewhere, or with another BLAS, none)."""
    import ctypes
    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f
                     if len(line.split()) >= 6 and "openblas" in line.split()[-1].lower()}
    except OSError:
        return []
    calls = []
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for set_name, get_name in _BLAS_THREADS:
            set_fn, get_fn = getattr(lib, set_name, None), getattr(lib, get_name, None)
            if set_fn is not None and get_fn is not None:
                set_fn.argtypes = [ctypes.c_int]
                calls.append((set_fn, get_fn))
                break
    return calls


@contextlib.contextmanager
def blas_single_thread() -> Iterator[None]:
    """OpenBLAS on one thread within the block, its thread count restored after.

    The diagnosis runs its simulations in worker processes, one per core; its own linear
    algebra (the QR factors and projections of :class:`Solver`, tens of thousands of rows by
    a few columns) is small, and OpenBLAS's threads spin against those workers for the
    cores: on the 2-core machine, one thread projects 7 times faster in wall time and
    spends 16 times less CPU (docs/diagnosis.md, "Where the time goes")."""
    calls = _blas_thread_calls()
    before = [int(get()) for _set, get in calls]
    for set_fn, _get in calls:
        set_fn(1)
    try:
        yield
    finally:
        for (set_fn, _get), n in zip(calls, before):
            set_fn(max(n, 1))
