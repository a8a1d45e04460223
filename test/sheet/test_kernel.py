"""Parts of the compiled sheet step (rheo_shaping.sheet.kernel) against independent references:
the banded Cholesky solve against a dense solve, the level-set curvature of every shape
kind against a finite difference of its normal, and the batched path against single steps."""
from __future__ import annotations

import numpy as np
import pytest

from rheo_shaping.sheet import kernel as K
from rheo_shaping.sheet.geometry import Cake, Workplane
from rheo_shaping.sheet.polygon import RoundedConvexPolygon
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.sheet.simulation import Simulation


@pytest.mark.parametrize("kd", [3, 4])
def test_band_cholesky_solves_like_a_dense_solve(kd):
    rng = np.random.default_rng(kd)
    m = 40
    dense = np.zeros((m, m))
    for k in range(1, kd + 1):
        off = rng.normal(size=m - k)
        dense += np.diag(off, k) + np.diag(off, -k)
    dense += np.diag(np.abs(dense).sum(axis=1) + rng.uniform(0.1, 1.0, m))   # SPD
    band = np.zeros((m, 5))
    for k in range(kd + 1):
        band[:m - k, k] = np.diag(dense, k)
    L = np.zeros((m, 6))
    assert K.band_cholesky(band, kd, L)
    b = rng.normal(size=m)
    out = np.empty(m)
    K.band_solve(L, kd, b, out)
    assert np.allclose(out, -np.linalg.solve(dense, b), rtol=1e-12, atol=1e-14)
    band[m // 2, 0] = -1.0                                   # not positive definite
    assert not K.band_cholesky(band, kd, L)


SHAPES = {
    "cake": Cake(0.03, 0.005),
    "sharp cake": Cake(0.03, 0.0),
    "workplane": Workplane(),
    "circle": RoundedConvexPolygon.circle(0.01),
    "capsule": RoundedConvexPolygon.rounded_rectangle(0.04, 0.01, 0.005),
    "rounded rectangle": RoundedConvexPolygon.rounded_rectangle(0.04, 0.02, 0.004),
    "triangle": RoundedConvexPolygon.convex_polygon([(0.0, 0.0), (0.02, 0.0), (0.0, 0.015)],
                                                    0.002),
}


@pytest.mark.parametrize("name", SHAPES)
def test_curvature_is_the_turning_of_the_normal_along_the_level_set(name):
    """kappa = dn/ds along the tangent (1/(d + R) round a corner, 0 on a face), outside."""
    shape = SHAPES[name]
    kind, rad, verts = shape.kernel_description()
    table = K.shape_table(verts)
    rng = np.random.default_rng(1)
    offset = (0.004, 0.031)
    pts = np.asarray(offset) + rng.uniform(-0.05, 0.05, size=(400, 2))
    d, n, kap = K.shape_eval_many(kind, len(verts), table, rad, pts, *offset)
    assert np.allclose(np.hypot(n[:, 0], n[:, 1]), 1.0, atol=1e-12)

    def turning(h):
        _, n2, _ = K.shape_eval_many(kind, len(verts), table, rad, pts + h * t, *offset)
        return np.einsum("ij,ij->i", n2 - n, t) / h

    t = np.column_stack((-n[:, 1], n[:, 0]))
    fd, fd_fine = turning(1e-7), turning(1e-8)
    # outside the shape, where contacts use it, and away from the seams where the nearest
    # feature switches (there the finite difference depends on its step)
    use = (d > 1e-3) & (np.abs(fd - fd_fine) < 1e-3 * np.maximum(np.abs(fd), 1.0))
    assert np.count_nonzero(use) > 0.9 * np.count_nonzero(d > 1e-3)
    assert np.allclose(kap[use], fd[use], rtol=1e-4, atol=1e-2)
    assert np.all(kap >= 0.0)
    if name == "workplane":
        assert np.all(kap == 0.0)


def test_run_path_takes_the_same_steps_as_single_steps():
    p = CellParams()
    plan = movement_plan(p, 4)
    a = Simulation(p, tool_start=plan.position(0.0))
    dts, tools = a.schedule(40.0, plan.position(40.0), plan.position)
    rec = a.model.run_path(a.state, dts, tools)
    st = a.state
    for k in range(len(dts)):
        st = a.model.step(st, dts[k], tools[k])
    assert len(rec) == len(dts) > 20
    assert rec.t[-1] == st.t
    assert np.array_equal(rec.x[-1], st.x)
    assert np.array_equal(rec.tension[-1], st.tension)
    assert np.array_equal(rec.contact[-1], st.contact)
    assert np.array_equal(rec.tool[-1], st.tool)
