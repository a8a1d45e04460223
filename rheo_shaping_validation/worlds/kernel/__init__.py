"""The dynamic world's compiled step (numba): a linearly implicit Euler step of a
chain of point masses with three-element links, soft penalty contact with
Coulomb friction (elastic-plastic anchors) and every effect of the world.

Written apart from :mod:`rheo_shaping.sheet.kernel` (no code in common): the
sheet model minimises an incremental potential by Newton to a quasi-static
equilibrium with a frictionless projection-like contact; this world takes one
linear solve per step of ~1 ms, with inertia, air damping, a soft contact of
finite stiffness and damping, and friction that sticks and slips.

One step of length ``h`` [s] (Baraff-Witkin form, positions ``x`` [m], velocities
``v`` [m/s], mass matrix ``M``):

    (M/h^2 + K + D/h) delta = M v/h + f(x),     x' = x + delta,  v' = delta/h

with ``f`` every force at the step's start (the obstacles at their END pose),
``K`` the positive semi-definite part of -df/dx (link axial and geometric
stiffness, contact normal and stick stiffness, bending) and ``D`` the damping
(air, contact).  ``K`` is banded: half bandwidth 3 in the x, z unknowns (5 with
bending); a banded Cholesky factor of our own solves it.

The link law (paper Eq. 2, k1 || c1 in series with c2) is integrated by the
backward Euler rule over the step, given the link's end length ``l'``:

    e1' = ((c1 + c2) e1 + c2 D) / (c1 + c2 + k1 h),   D = l' - (L0 + e1 + p)
    F'  = k1 e1' + c1 (e1' - e1)/h,                   p' = p + D - (e1' - e1)

(affine in ``l'``: F' = A + S D), slack (F' < 0): F' = 0, p' = p,
e1' = c1 e1/(c1 + k1 h).  First order in h: 1e-4 of the force at h = 1 ms for the
paper's Maxwell constants (Eq. 5, 7-8 in test/worlds).

Modules: ``consts`` (numba options, packed-parameter indices), ``obstacles`` (gaps and
normals, the push-out of a laid sheet), ``links`` (the link law, the banded solve),
``assemble`` (one step's linear system), ``run`` (the compiled loop over a path).
The compiled code is cached by content (:mod:`rheo_shaping._numba_cache`), like the sheet's
kernel: a change in any of this package's modules compiles them all anew.
"""
from __future__ import annotations

from pathlib import Path

from rheo_shaping._numba_cache import register

register(Path(__file__).resolve().parent, "rheo_shaping_worlds")

from .consts import *  # noqa: E402,F401,F403
from .obstacles import cake_gap, obstacle_gap, polygon_gap, push_out  # noqa: E402,F401
from .links import (add_block, link_affine, link_constants, link_update,  # noqa: E402,F401
                    pb_factor, pb_solve)
from .assemble import add_contact, assemble  # noqa: E402,F401
from .run import run_chain  # noqa: E402,F401

#: The compiled step's entry points (the packed-parameter indices of ``consts`` are
#: reached as attributes, ``kernel.X_N``).
__all__ = ["cake_gap", "obstacle_gap", "polygon_gap", "push_out", "add_block", "link_affine",
           "link_constants", "link_update", "pb_factor", "pb_solve", "add_contact", "assemble",
           "run_chain"]
