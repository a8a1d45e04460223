"""The sheet step as one compiled (numba) kernel: the only implementation of the step.

Its modules: ``consts`` (kinds, status codes, packed-parameter indices), ``shapes``
(obstacle distances), ``links`` (the link law and the banded solve), ``potential``
(energy, gradient, Hessian), ``newton`` (the minimisation), ``step`` (one step, many
steps, a path) and ``pack`` (the arrays, from the model).

:class:`rheo_shaping.sheet.chain.SheetModel` packs its chain, obstacles and effects
into a few arrays (:func:`pack_model`) and calls :func:`advance`, which takes
one step of ``dt`` [s] (with the half-step retries) or :func:`advance_fixed`,
which takes many equal steps (the inertial settle) without returning to
Python in between.  Everything the step needs is here, compiled: the
three-element link update (material.py's exact step, paper Eq. 2-5), the
obstacles' signed distances, normals and level-set curvature (shapes as small
array descriptions, :func:`shape_eval`), the incremental potential with its
gradient and banded Hessian, the contact-set prediction, a banded Cholesky
solve (half bandwidth 3, 4 with bending), the backtracking line search, and
every effect of :mod:`rheo_shaping.sheet.effects` (friction, bending, Kelvin c1,
power law, thinning, tool offset, mass error).

Compiled code is cached on disk (``cache=True``) in a user cache directory,
so a read-only install (colcon prefix, site-packages) compiles once per user:
``$NUMBA_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/rheo_shaping/numba``
(``~/.cache/rheo_shaping/numba``).  The cache is found by the content of the
kernel's modules and the numba version, not their path (:class:`_ContentCacheLocator`), so
every install of the same source on the same numba (a checkout, site-packages, a colcon
prefix) shares it, a change in any module (numba inlines the calls between them) compiles
them all anew, and venvs with different numbas (.venv-core, .venv-noble) keep apart.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

HERE = Path(__file__).resolve().parent


def user_cache_dir() -> str:
    """Directory [path] where the compiled kernel is cached for this user."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return str(Path(base) / "rheo_shaping" / "numba")


if not os.environ.get("NUMBA_CACHE_DIR"):
    os.environ["NUMBA_CACHE_DIR"] = user_cache_dir()
    if "numba" in sys.modules:                     # numba read its config already
        sys.modules["numba"].config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]

from numba.core import caching as _caching  # noqa: E402

# the user-directory locator: UserProvidedCacheLocator in the numba of requirements-core
# (0.68 here); numba 0.59, Ubuntu 24.04's python3-numba (what rosdep installs for Jazzy),
# has it only as _UserProvidedCacheLocator.  The type check reads numba 0.68's types.
if TYPE_CHECKING:
    from numba.core.caching import UserProvidedCacheLocator as _UserDirLocator
else:
    _UserDirLocator = getattr(_caching, "UserProvidedCacheLocator", None) \
        or _caching._UserProvidedCacheLocator


def cache_folder() -> str:
    """Name of the kernel's cache folder in ``$NUMBA_CACHE_DIR``: the source's content and
    the numba version (numba's index holds the entries of one numba version and a
    mismatch empties it, so two venvs with two numbas in one folder would each compile
    anew every run, overwriting the other's)."""
    import numba
    return f"rheo_shaping_{source_digest()}_numba{numba.__version__}"


def source_digest() -> str:
    """SHA-256 (20 hex digits) of the kernel's modules: names and contents."""
    h = hashlib.sha256()
    for path in sorted(HERE.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:20]


class _ContentCacheLocator(_UserDirLocator):
    """numba's user-directory cache, with the folder named by the kernel's source content
    and the numba version (:func:`cache_folder`) instead of its directory: a new install
    of the same source finds the code compiled by an earlier one (numba checks its own
    version and the CPU in the index)."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        # numba's config sets its options at run time (from the environment): getattr, as
        # its types do not list them
        self._cache_path = os.path.join(getattr(_caching.config, "CACHE_DIR"), cache_folder())

    @classmethod
    def from_function(cls, py_func, py_file):
        if Path(py_file).resolve().parent != HERE:
            return None                           # only the kernel's functions
        return super().from_function(py_func, py_file)


if _ContentCacheLocator not in _caching.CacheImpl._locator_classes:
    _caching.CacheImpl._locator_classes.insert(0, _ContentCacheLocator)

from .consts import (CAKE_KIND, NOT_CONVERGED, NOT_SPD, OK, PLANE_KIND,  # noqa: E402
                     POLYGON_KIND, ST_EVAL, ST_FAILED, ST_NEWTON, ST_SOLVE, ST_SUBSTEPS)
from .links import band_cholesky, band_solve, link_constants  # noqa: E402
from .newton import minimise, newton_step  # noqa: E402
from .pack import pack_model, shape_table  # noqa: E402
from .potential import bending_terms, evaluate  # noqa: E402
from .shapes import shape_eval, shape_eval_many  # noqa: E402
from .step import advance, advance_fixed, advance_path, one_step  # noqa: E402

__all__ = ["CAKE_KIND", "PLANE_KIND", "POLYGON_KIND", "OK", "NOT_CONVERGED", "NOT_SPD",
           "ST_NEWTON", "ST_EVAL", "ST_SOLVE", "ST_SUBSTEPS", "ST_FAILED", "band_cholesky",
           "band_solve", "link_constants", "minimise", "newton_step", "pack_model",
           "shape_table", "bending_terms", "evaluate", "shape_eval", "shape_eval_many",
           "advance", "advance_fixed", "advance_path", "one_step", "user_cache_dir",
           "source_digest", "cache_folder"]
