"""Signed distances and normals of the obstacle shapes (rheo_shaping.sheet.geometry)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from matplotlib.path import Path
from scipy.spatial import ConvexHull

from rheo_shaping.params.cell import ToolParams
from rheo_shaping.sheet.geometry import Cake, Workplane
from rheo_shaping.sheet.polygon import circle, convex_polygon, rounded_rectangle
from rheo_shaping.sheet.tools import tool_shape

RNG = np.random.default_rng(20240607)


# ------------------------------------------------------------- brute force


def dense_rounded_boundary(vertices: np.ndarray, r: float, spacing: float) -> np.ndarray:
    """Points every ~``spacing`` m on the boundary of polygon (+) disc, built
    independently of the module: edges shifted out by r, arcs round vertices
    from one edge's normal to the next one's."""
    v = np.atleast_2d(np.asarray(vertices, float))
    k = len(v)
    if k == 1:
        n = max(16, int(2 * math.pi * r / spacing))
        phi = np.linspace(0, 2 * math.pi, n, endpoint=False)
        return v[0] + r * np.column_stack((np.cos(phi), np.sin(phi)))
    e = np.roll(v, -1, axis=0) - v
    ang = np.arctan2(-e[:, 0], e[:, 1])               # angle of the outward normal (e_z, -e_x)
    pts = []
    for i in range(k):
        a, b = v[i], v[(i + 1) % k]
        nrm = np.array([math.cos(ang[i]), math.sin(ang[i])])
        n = max(2, int(np.hypot(*e[i]) / spacing))
        t = np.linspace(0, 1, n)[:, None]
        pts.append(a + r * nrm + t * e[i])
        if r > 0:
            turn = math.pi if k == 2 else (ang[(i + 1) % k] - ang[i]) % (2 * math.pi)
            m = max(4, int(turn * r / spacing))
            phi = ang[i] + np.linspace(0, turn, m)
            pts.append(b + r * np.column_stack((np.cos(phi), np.sin(phi))))
    return np.vstack(pts)


def _dist_to_polygon(p: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unsigned distance from points p (M, 2) to the filled convex polygon,
    segment or point v (0 inside)."""
    k = len(v)
    if k == 1:
        return np.hypot(*(p - v[0]).T)
    best = np.full(len(p), np.inf)
    for i in range(k if k >= 3 else 1):
        a, b = v[i], v[(i + 1) % k]
        e = b - a
        t = np.clip((p - a) @ e / (e @ e), 0.0, 1.0)
        best = np.minimum(best, np.hypot(*(p - a - t[:, None] * e).T))
    if k >= 3:
        best[Path(v).contains_points(p)] = 0.0
    return best


def brute_signed_distance(points: np.ndarray, boundary: np.ndarray,
                          inside: np.ndarray) -> np.ndarray:
    dmin = np.sqrt(((points[:, None, :] - boundary[None, :, :]) ** 2).sum(-1)).min(axis=1)
    return np.where(inside, -dmin, dmin)


def rounded_inside(points: np.ndarray, vertices: np.ndarray, r: float) -> np.ndarray:
    v = np.atleast_2d(np.asarray(vertices, float))
    return _dist_to_polygon(points, v) <= r if r > 0 else Path(v).contains_points(points)


def fd_gradient(shape, points: np.ndarray, h: float = 1e-7, offset=(0.0, 0.0)) -> np.ndarray:
    g = np.empty_like(points)
    for c in range(2):
        dp = np.zeros(2)
        dp[c] = h
        g[:, c] = (shape.signed_distance(points + dp, offset)[0] -
                   shape.signed_distance(points - dp, offset)[0]) / (2 * h)
    return g


def polygon_medial_gap(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """For points inside the polygon: gap between the two largest edge-line
    distances (0 on the medial axis); +inf outside the polygon."""
    v = np.asarray(vertices, float)
    e = np.roll(v, -1, axis=0) - v
    nrm = np.column_stack((e[:, 1], -e[:, 0])) / np.hypot(e[:, 0], e[:, 1])[:, None]
    s = np.einsum("mkc,kc->mk", points[:, None, :] - v[None], nrm)
    s_sorted = np.sort(s, axis=1)
    gap = s_sorted[:, -1] - s_sorted[:, -2]
    return np.where(s_sorted[:, -1] > 0, np.inf, gap)


TOOLS = {
    "circle": circle(0.01),
    "rounded_rectangle": rounded_rectangle(0.02, 0.04, 0.008),
    "sharp_rectangle": rounded_rectangle(0.02, 0.04, 0.0),
    "triangle": convex_polygon([[0.0, 0.0], [0.03, 0.005], [0.01, 0.025]], 0.003),
    "capsule": rounded_rectangle(0.02, 0.04, 0.01),
    "pentagon": convex_polygon([[math.cos(a) * 0.02, math.sin(a) * 0.02]
                                for a in np.linspace(0, 2 * math.pi, 5, endpoint=False)], 0.001),
}


# ------------------------------------------------------------------ tools


@pytest.mark.parametrize("name", sorted(TOOLS))
def test_tool_distance_matches_brute_force(name):
    tool = TOOLS[name]
    v = np.asarray(tool.vertices)
    offset = np.array([0.013, -0.007])
    pts = offset + RNG.uniform(-0.04, 0.04, (300, 2))
    d, n = tool.signed_distance(pts, offset)
    spacing = 2e-5
    boundary = dense_rounded_boundary(v, tool.radius, spacing)
    inside = rounded_inside(pts - offset, v, tool.radius)
    d_ref = brute_signed_distance(pts - offset, boundary, inside)
    assert np.abs(d - d_ref).max() < spacing
    assert np.array_equal(d <= 0, inside | (np.abs(d_ref) < 1e-12))
    assert np.allclose(np.hypot(n[:, 0], n[:, 1]), 1.0, atol=1e-14)


@pytest.mark.parametrize("name", sorted(TOOLS))
def test_tool_normal_is_gradient_away_from_medial_axis(name):
    tool = TOOLS[name]
    v = np.asarray(tool.vertices)
    pts = RNG.uniform(-0.04, 0.04, (400, 2))
    if len(v) >= 3:
        pts = pts[polygon_medial_gap(pts, v) > 1e-5]
    else:   # the medial axis of a circle / capsule is its centre / core segment
        d, _ = tool.signed_distance(pts)
        pts = pts[d > -tool.radius + 1e-5]
    _, n = tool.signed_distance(pts)
    assert np.abs(fd_gradient(tool, pts) - n).max() < 1e-6


@pytest.mark.parametrize("name", sorted(TOOLS))
def test_projection_lands_on_boundary(name):
    """p - d n is the nearest boundary point: distance 0 there, same normal outside."""
    tool = TOOLS[name]
    pts = RNG.uniform(-0.04, 0.04, (300, 2))
    d, n = tool.signed_distance(pts)
    foot = pts - d[:, None] * n
    d_foot, n_foot = tool.signed_distance(foot)
    assert np.abs(d_foot).max() < 1e-15 + 1e-12 * np.abs(d).max()
    if tool.radius > 0:         # a sharp corner has no single normal on the boundary
        out = d > 1e-9
        assert np.abs(n_foot[out] - n[out]).max() < 1e-9


def test_circle_closed_form():
    r = 0.0125
    tool = circle(r)
    c = np.array([0.03, 0.11])
    pts = RNG.normal(size=(500, 2)) * 0.02 + c
    d, n = tool.signed_distance(pts, c)
    rel = pts - c
    dist = np.hypot(rel[:, 0], rel[:, 1])
    assert np.allclose(d, dist - r, rtol=0, atol=1e-16)
    assert np.allclose(n, rel / dist[:, None], rtol=0, atol=1e-15)
    # centre: a unit normal, d = -r
    d0, n0 = tool.signed_distance(c[None], c)
    assert d0[0] == -r and np.isclose(np.hypot(*n0[0]), 1.0)
    # a one-vertex polygon plus radius is the circle
    same = convex_polygon([[0.0, 0.0]], r)
    assert np.array_equal(same.signed_distance(pts, c)[0], d)


def test_offset_translates_and_contains():
    tool = TOOLS["rounded_rectangle"]
    pts = RNG.uniform(-0.05, 0.05, (50, 2))
    off = (0.02, 0.031)
    d1, n1 = tool.signed_distance(pts, off)
    d2, n2 = tool.signed_distance(pts - np.array(off))
    assert np.allclose(d1, d2, atol=1e-16) and np.allclose(n1, n2, atol=1e-12)
    assert np.array_equal(tool.contains(pts, off), d1 <= 0)
    # single point (2,) is accepted
    d, n = tool.signed_distance((0.0, 0.0))
    assert d.shape == (1,) and n.shape == (1, 2) and d[0] == pytest.approx(-0.01)


def test_rounded_rectangle_geometry():
    tool = rounded_rectangle(0.02, 0.04, 0.008)
    # faces at x = +-0.01 and z = +-0.02
    d, n = tool.signed_distance(np.array([[0.015, 0.0], [0.0, -0.03], [0.005, 0.0], [0.0, 0.019]]))
    assert np.allclose(d, [0.005, 0.01, -0.005, -0.001], atol=1e-16)
    assert np.allclose(n, [[1, 0], [0, -1], [1, 0], [0, 1]])
    # corner region: distance from the corner centre minus the corner radius
    cc = np.array([0.002, 0.012])
    p = cc + 0.02 * np.array([math.cos(0.7), math.sin(0.7)])
    assert tool.signed_distance(p)[0][0] == pytest.approx(0.02 - 0.008, abs=1e-15)
    # degenerate radii: capsule and circle
    assert rounded_rectangle(0.02, 0.04, 0.01).n_vertices == 2
    assert rounded_rectangle(0.02, 0.02, 0.01).n_vertices == 1


@pytest.mark.parametrize("name", sorted(TOOLS))
def test_tool_outline_on_boundary(name):
    tool = TOOLS[name]
    pts = tool.outline(97, offset=(0.1, 0.2))
    assert pts.shape == (97, 2)
    d, _ = tool.signed_distance(pts, (0.1, 0.2))
    assert np.abs(d).max() < 1e-15
    # counter-clockwise: positive shoelace area close to the true area
    x, z = pts[:, 0], pts[:, 1]
    area = 0.5 * np.sum(x * np.roll(z, -1) - np.roll(x, -1) * z)
    assert area > 0


def test_tool_validation_errors():
    with pytest.raises(ValueError, match="clockwise"):
        convex_polygon([[0, 0], [0, 1], [1, 1], [1, 0]])
    with pytest.raises(ValueError, match="vertex 2"):
        convex_polygon([[0, 0], [1, 0], [0.5, 0.2], [1, 1], [0, 1]])     # reflex vertex
    with pytest.raises(ValueError, match="collinear"):
        convex_polygon([[0, 0], [0.5, 0], [1, 0], [1, 1], [0, 1]])
    with pytest.raises(ValueError, match="repeats"):
        convex_polygon([[0, 0], [1, 0], [1, 0], [1, 1]])
    star = [[math.cos(a), math.sin(a)] for a in np.linspace(0, 4 * math.pi, 5, endpoint=False)]
    with pytest.raises(ValueError, match="wind"):
        convex_polygon(star)
    with pytest.raises(ValueError, match="radius"):
        convex_polygon([[0, 0], [1, 0], [0, 1]], -0.1)
    with pytest.raises(ValueError, match=r"radius \[m\]: 0\.0"):
        convex_polygon([[0, 0]], 0.0)
    with pytest.raises(ValueError, match="corner_radius"):
        rounded_rectangle(0.02, 0.04, 0.011)
    with pytest.raises(ValueError, match="width"):
        rounded_rectangle(-0.02, 0.04, 0.001)
    with pytest.raises(ValueError, match="vertices"):
        convex_polygon([[0, 0, 0]])
    with pytest.raises(ValueError, match="points"):
        circle(0.01).signed_distance(np.zeros((3, 3)))


def test_tool_shape_from_params():
    """The one tool-shape builder (sheet.tools.tool_shape) for each ToolParams shape."""
    tool = ToolParams(shape="polygon", radius=0.01, width=0.02, height=0.04,
                      corner_radius=0.001, vertices=(0.0, 0.0, 0.02, 0.0, 0.02, 0.04, 0.0, 0.04))
    t = tool_shape(tool)
    assert t.n_vertices == 4 and t.radius == 0.001
    assert tool_shape(replace(tool, shape="rounded_rectangle")) == rounded_rectangle(0.02, 0.04,
                                                                                     0.001)
    assert tool_shape(replace(tool, shape="circle")) == circle(0.01)


# ----------------------------------------------------------- hypothesis


@st.composite
def convex_polygons(draw):
    n = draw(st.integers(3, 9))
    coords = draw(st.lists(st.tuples(st.floats(-0.03, 0.03),
                  st.floats(-0.03, 0.03)), min_size=n, max_size=n))
    pts = np.array(coords)
    assume(np.ptp(pts[:, 0]) > 2e-3 and np.ptp(pts[:, 1]) > 2e-3)
    try:
        hull = ConvexHull(pts)
    except Exception:
        assume(False)
    v = pts[hull.vertices]                               # counter-clockwise in 2-D
    assume(hull.volume > 1e-6)
    e = np.roll(v, -1, axis=0) - v
    e2 = np.roll(e, -1, axis=0)
    cross = e[:, 0] * e2[:, 1] - e[:, 1] * e2[:, 0]
    assume(np.hypot(e[:, 0], e[:, 1]).min() > 1e-4 and cross.min() > 1e-9)
    r = draw(st.sampled_from([0.0, 1e-4, 2e-3, 1e-2]))
    return v, r


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow])
@given(poly=convex_polygons(), seed=st.integers(0, 2**32 - 1))
def test_random_convex_polygon_against_brute_force(poly, seed):
    v, r = poly
    tool = convex_polygon(v, r)
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-0.05, 0.05, (60, 2))
    pts = np.vstack((pts, v + rng.normal(scale=1e-3, size=v.shape)))   # near the corners too
    d, n = tool.signed_distance(pts)
    spacing = 5e-5
    boundary = dense_rounded_boundary(v, r, spacing)
    inside = rounded_inside(pts, v, r)
    d_ref = brute_signed_distance(pts, boundary, inside)
    assert np.abs(d - d_ref).max() < spacing
    assert np.allclose(np.hypot(n[:, 0], n[:, 1]), 1.0, atol=1e-13)
    ok = polygon_medial_gap(pts, v) > 1e-5
    assert np.abs(fd_gradient(tool, pts[ok], h=1e-8) - n[ok]).max() < 1e-5


@settings(max_examples=60, deadline=None)
@given(h=st.floats(0.02, 0.3), frac=st.floats(0.0, 1.0), seed=st.integers(0, 2**32 - 1))
def test_random_cake_normals_and_projection(h, frac, seed):
    cake = Cake(h, frac * h * 0.9, 0.5)
    rng = np.random.default_rng(seed)
    pts = np.array([0.0, h]) + rng.uniform(-0.06, 0.06, (80, 2))
    d, n = cake.signed_distance(pts)
    assert np.allclose(np.hypot(n[:, 0], n[:, 1]), 1.0, atol=1e-14)
    foot = pts - d[:, None] * n
    assert np.abs(cake.signed_distance(foot)[0]).max() < 1e-15


# ------------------------------------------------------------------- cake


def cake_inside(p: np.ndarray, h: float, r: float) -> np.ndarray:
    x, z = p[:, 0], p[:, 1]
    basic = (x <= 0) & (z <= h)
    corner = (x > -r) & (z > h - r)
    in_fillet = np.hypot(x + r, z - (h - r)) <= r
    return basic & (~corner | in_fillet)


def cake_boundary(h: float, r: float, spacing: float, reach: float = 0.3) -> np.ndarray:
    top = np.column_stack((np.arange(-reach, -r, spacing),
                          np.full(int(np.ceil((reach - r) / spacing)), h)))
    wall_z = np.arange(h - r, h - reach, -spacing)
    wall = np.column_stack((np.zeros_like(wall_z), wall_z))
    parts = [top, wall]
    if r > 0:
        phi = np.linspace(0, math.pi / 2, max(8, int(r * math.pi / 2 / spacing)))
        parts.append(np.column_stack((-r + r * np.cos(phi), h - r + r * np.sin(phi))))
    return np.vstack(parts)


@pytest.mark.parametrize("r", [0.0, 0.004, 0.01, 0.08])
def test_cake_distance_matches_brute_force(r):
    h = 0.08
    cake = Cake(h, r, 0.09)
    pts = np.array([0.0, h]) + RNG.uniform(-0.06, 0.06, (300, 2))
    d, n = cake.signed_distance(pts)
    spacing = 2e-5
    d_ref = brute_signed_distance(pts, cake_boundary(h, r, spacing), cake_inside(pts, h, r))
    assert np.abs(d - d_ref).max() < spacing
    assert np.allclose(np.hypot(n[:, 0], n[:, 1]), 1.0, atol=1e-14)
    # normal = gradient, away from the interior medial axis (the diagonal from the fillet centre)
    q = pts - np.array([-r, h - r])
    ok = ~((q[:, 0] < 0) & (q[:, 1] < 0) & (np.abs(q[:, 0] - q[:, 1]) < 1e-5))
    assert np.abs(fd_gradient(cake, pts[ok]) - n[ok]).max() < 1e-6


def test_cake_fillet_is_centre_distance_minus_radius():
    h, r = 0.08, 0.01
    cake = Cake(h, r, 0.09)
    centre = np.array([-r, h - r])
    phi = RNG.uniform(0, math.pi / 2, 200)
    rho = RNG.uniform(0.0, 0.05, 200)
    pts = centre + rho[:, None] * \
        np.column_stack((np.cos(phi), np.sin(phi)))   # the corner quadrant
    d, n = cake.signed_distance(pts)
    assert np.allclose(d, rho - r, atol=1e-16)
    assert np.allclose(n[rho > 1e-9], np.column_stack((np.cos(phi), np.sin(phi)))
                       [rho > 1e-9], atol=1e-12)
    # top, wall and inside faces
    d, n = cake.signed_distance(
        np.array([[-0.05, h + 0.003], [0.004, 0.03], [-0.05, h - 0.002], [-0.001, 0.03]]))
    assert np.allclose(d, [0.003, 0.004, -0.002, -0.001], atol=1e-16)
    assert np.allclose(n, [[0, 1], [1, 0], [0, 1], [1, 0]])
    # offset moves the cake
    d2, _ = cake.signed_distance(np.array([[0.01, 0.03]]), offset=(0.01, 0.0))
    assert d2[0] == pytest.approx(0.0, abs=1e-16)


def test_cake_outline_and_validation():
    cake = Cake(0.08, 0.01, 0.09)
    pts = cake.outline(40)
    assert pts.shape == (40, 2)
    assert np.allclose(pts[0], [-0.09, 0.08]) and np.allclose(pts[-1], [0.0, 0.0])
    assert np.abs(cake.signed_distance(pts)[0]).max() < 1e-15
    closed = cake.outline(60, closed=True)
    assert closed.shape == (60, 2) and np.allclose(closed[0], [-0.09, 0.08])
    assert Cake(0.08, 0.0, 0.09).outline(10).shape == (10, 2)
    with pytest.raises(ValueError, match="fillet_radius"):
        Cake(0.08, 0.09, 0.2)
    with pytest.raises(ValueError, match="height"):
        Cake(-0.08, 0.01, 0.09)
    with pytest.raises(ValueError, match="fillet_radius"):
        Cake(0.08, -0.01, 0.09)
    assert Cake(0.08, 0.01, 0.09).contains(
        np.array([[-0.01, 0.07], [0.001, 0.07]])).tolist() == [True, False]


# -------------------------------------------------------------- workplane


def test_workplane():
    wp = Workplane()
    pts = RNG.uniform(-0.1, 0.1, (20, 2))
    d, n = wp.signed_distance(pts)
    assert np.array_equal(d, pts[:, 1])
    assert np.array_equal(n, np.tile([0.0, 1.0], (20, 1)))
    d2, _ = wp.signed_distance(pts, offset=(0.3, 0.01))
    assert np.allclose(d2, pts[:, 1] - 0.01)
    assert np.array_equal(wp.contains(pts), pts[:, 1] <= 0)
    out = wp.outline(5)
    assert out.shape == (5, 2) and np.all(out[:, 1] == 0)
    with pytest.raises(ValueError, match="x_max"):
        Workplane(0.1, 0.0)
