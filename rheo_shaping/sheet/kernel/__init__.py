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
kernel's modules and the numba version, not their path (:mod:`rheo_shaping._numba_cache`), so
every install of the same source on the same numba (a checkout, site-packages, a colcon
prefix) shares it, a change in any module (numba inlines the calls between them) compiles
them all anew, and venvs with different numbas (.venv-core, .venv-noble) keep apart.
"""
from __future__ import annotations

from pathlib import Path

from ..._numba_cache import cache_folder as _folder
from ..._numba_cache import register, source_digest as _digest
from ..._numba_cache import user_cache_dir  # noqa: F401 (where the cache is)

HERE = Path(__file__).resolve().parent
register(HERE, "rheo_shaping")


def cache_folder() -> str:
    """Name of the kernel's cache folder in ``$NUMBA_CACHE_DIR`` (the source's content and
    the numba version: :func:`rheo_shaping._numba_cache.cache_folder`)."""
    return _folder(HERE)


def source_digest() -> str:
    """SHA-256 (20 hex digits) of the kernel's modules: names and contents."""
    return _digest(HERE)


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
