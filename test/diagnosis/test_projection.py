"""The compiled projection of profile points on the model's centrelines
(:func:`rheo_shaping.diagnosis.kernel.project`) against closed forms, and against the array
formulation it replaced on a real run (the residuals must not move)."""
import math

import numpy as np

from rheo_shaping_validation.benchmark import base_cell
from rheo_shaping.diagnosis.compare import RecordData, polylines_at, simulate
from rheo_shaping.diagnosis.kernel import project
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams


def _array_projection(points, frame, lines):
    """Every segment of every point's frame at once, the nearest (first of equal distance);
    the normal from np.gradient tangents interpolated in arc length (the former code)."""
    a = lines[frame, :-1]
    seg = lines[frame, 1:] - a
    L2 = np.einsum("psk,psk->ps", seg, seg)
    rel = points[:, None, :] - a
    s = np.clip(np.einsum("psk,psk->ps", rel, seg) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    foot = a + s[..., None] * seg
    d2 = np.einsum("psk,psk->ps", points[:, None, :] - foot, points[:, None, :] - foot)
    j = np.argmin(d2, axis=1)
    i = np.arange(len(j))
    seg_j, foot_j = seg[i, j], foot[i, j]
    cross = (seg_j[:, 0] * (points[:, 1] - foot_j[:, 1])
             - seg_j[:, 1] * (points[:, 0] - foot_j[:, 0]))
    dist = np.sqrt(d2[i, j]) * np.sign(cross)
    cum = np.concatenate((np.zeros((len(lines), 1)), np.cumsum(
        np.linalg.norm(np.diff(lines, axis=1), axis=2), axis=1)), axis=1)
    arc = cum[frame, j] + s[i, j] * np.sqrt(L2[i, j])
    tang = np.gradient(lines, axis=1)
    normal = np.empty((len(arc), 2))
    for f in np.unique(frame):
        sel = frame == f
        tx = np.interp(arc[sel], cum[f], tang[f, :, 0])
        tz = np.interp(arc[sel], cum[f], tang[f, :, 1])
        n = np.hypot(tx, tz)
        normal[sel] = np.c_[-tz, tx] / np.where(n > 0, n, 1.0)[:, None]
    return dist, arc, foot_j, normal


def test_points_off_a_bent_polyline_have_their_closed_form_distance_arc_and_normal():
    # frame 0: from (0, 1) right to (1, 1), then down to (1, 0); frame 1: the same moved up 1
    line = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0]])
    lines = np.stack((line, line + [0.0, 1.0]))
    points = np.array([[0.25, 1.5],     # above the first leg: left of it (+), 0.5 away
                       [0.5, 0.75],     # below the first leg (-), 0.25 from it
                       [1.3, 0.4],      # right of the second leg: its left is +x (+ side)
                       [-0.2, 1.0],     # before the start: the first node is the foot
                       [0.25, 2.5]])    # frame 1: 0.5 above its first leg
    frame = np.array([0, 0, 0, 0, 1])
    dist, arc, foot, normal = project(points, frame, lines)
    np.testing.assert_allclose(dist, [0.5, -0.25, 0.3, 0.0, 0.5], atol=1e-15)
    np.testing.assert_allclose(arc, [0.25, 0.5, 1.6, 0.0, 0.25], atol=1e-15)
    np.testing.assert_allclose(foot, [[0.25, 1.0], [0.5, 1.0], [1.0, 0.4], [0.0, 1.0],
                                      [0.25, 2.0]], atol=1e-15)
    # node tangents (1, 0), (0.5, -0.5), (0, -1); at arc 0.25 of the first leg:
    # (1, 0) + 0.25 ((0.5, -0.5) - (1, 0)) = (0.875, -0.125)
    t = np.array([0.875, -0.125]) / math.hypot(0.875, -0.125)
    np.testing.assert_allclose(normal[0], [-t[1], t[0]], atol=1e-15)
    np.testing.assert_allclose(normal[3], [0.0, 1.0], atol=1e-15)
    # on the second leg at 0.6 of it: (0.5, -0.5) + 0.6 ((0, -1) - (0.5, -0.5)) = (0.2, -0.8)
    t = np.array([0.2, -0.8]) / math.hypot(0.2, -0.8)
    np.testing.assert_allclose(normal[2], [-t[1], t[0]], atol=1e-15)


def test_the_kernel_gives_the_array_formulation_s_residual_geometry_on_a_run():
    rec, _ = synthesize_record(base_cell(15, 30.0), MeasurementParams(), seed=5)
    data = RecordData.of(rec)
    lines = polylines_at(simulate(rec.scenario, data), rec.profile_t)
    got = project(data.point_xz, data.point_frame, lines)
    want = _array_projection(data.point_xz, data.point_frame, lines)
    assert data.point_xz.shape[0] > 1000
    for g, w, tol in zip(got, want, (0.0, 1e-15, 0.0, 1e-13)):
        np.testing.assert_allclose(g, w, rtol=0.0, atol=tol)
