"""Evaluation geometry: exact closest points on a surface, Table 1 plumbing."""

import numpy as np
import pytest
import trimesh

from seatkit.geometry.closest import closest_point_on_triangles
from seatkit.geometry.surface import SurfaceQuery
from seatkit.model import Surface


def _bumpy_surface(n=24):
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, n + 1), np.linspace(-0.5, 0.5, n + 1), indexing="ij")
    y = 0.1 * np.sin(3 * u) * np.cos(2 * v)
    verts = np.stack([u, y, v], axis=-1).reshape(-1, 3)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(-1, 4)
    tm = trimesh.Trimesh(verts, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]), process=False)
    normals = np.asarray(tm.vertex_normals)
    if normals[:, 1].mean() < 0:
        normals = -normals
    return Surface(verts, normals, quads, 0), tm


def test_closest_point_on_triangle_regions():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    cases = {
        (0.2, 0.2, 1.0): (0.2, 0.2, 0.0),  # interior
        (-1.0, -1.0, 0.0): (0.0, 0.0, 0.0),  # vertex a
        (2.0, -0.5, 0.0): (1.0, 0.0, 0.0),  # vertex b
        (0.5, -1.0, 0.3): (0.5, 0.0, 0.0),  # edge ab
        (1.0, 1.0, 0.0): (0.5, 0.5, 0.0),  # edge bc
        (-0.5, 0.5, 0.0): (0.0, 0.5, 0.0),  # edge ca
    }
    for p, want in cases.items():
        got, bary = closest_point_on_triangles(np.array(p), a, b, c)
        np.testing.assert_allclose(got, want, atol=1e-12)
        assert bary.sum() == pytest.approx(1.0)


def test_surface_query_matches_brute_force_near_the_surface():
    surface, tm = _bumpy_surface()
    rng = np.random.default_rng(0)
    pts = rng.uniform([-0.45, -0.15, -0.45], [0.45, 0.2, 0.45], size=(600, 3))
    dist, side = SurfaceQuery(surface).query(pts)
    # brute force: every point against every triangle
    tri = tm.vertices[tm.faces]
    closest, _ = closest_point_on_triangles(pts[:, None, :], tri[None, :, 0], tri[None, :, 1], tri[None, :, 2])
    ref = np.linalg.norm(closest - pts[:, None, :], axis=2).min(axis=1)
    np.testing.assert_allclose(dist, ref, atol=1e-12)
    # sign: above the height field is the normal (+Y) side
    height = 0.1 * np.sin(3 * pts[:, 0]) * np.cos(2 * pts[:, 2])
    clear = np.abs(pts[:, 1] - height) > 0.01
    assert np.all(np.sign(side[clear]) == np.sign(pts[clear, 1] - height[clear]))


def test_surface_query_within_skips_only_points_that_are_farther():
    surface, tm = _bumpy_surface(12)  # coarse: a large reach
    rng = np.random.default_rng(1)
    pts = rng.uniform([-0.8, -0.6, -0.8], [0.8, 0.6, 0.8], size=(3000, 3))
    query = SurfaceQuery(surface)
    edges = np.linalg.norm(tm.vertices[tm.edges[:, 0]] - tm.vertices[tm.edges[:, 1]], axis=1)
    assert 0 < query.reach <= edges.max()
    full, side_full = query.query(pts)
    within = rng.uniform(0.0, 0.2, size=len(pts))
    dist, side = query.query(pts, within=within)
    searched = np.isfinite(dist)
    assert 0 < searched.sum() < len(pts)
    # searched points: the same numbers as a full search, bit for bit
    assert dist[searched].tobytes() == full[searched].tobytes()
    assert side[searched].tobytes() == side_full[searched].tobytes()
    # skipped points are farther than asked, and say so
    assert np.all(full[~searched] > within[~searched])
    assert np.isnan(side[~searched]).all()
    # a scalar works too; no points, no work
    near = query.query(pts, within=0.05)[0]
    assert np.all(np.isfinite(near[full <= 0.05]))
    assert np.all(full[~np.isfinite(near)] > 0.05)
    assert query.query(np.zeros((0, 3)))[0].shape == (0,)


def test_design_file_round_trips(tmp_path):
    from seatkit.model import Body, BuildResult, ControlMesh
    from seatkit.state import load_design, save_design

    rng = np.random.default_rng(1)
    vertices = rng.normal(size=(10, 3)) * 0.4  # about 1.3 m across: load_design refuses what is not a person's size
    body = Body(
        vertices=vertices,
        faces=np.array([[0, 1, 2], [2, 3, 4]]),
        weights=np.full((10, 21), 1 / 21),
        joints=vertices[rng.integers(0, 10, 21)],
        tips=vertices[rng.integers(0, 10, 21)],
        segment_mass=np.full(21, 75 / 21),
        segment_com=vertices[rng.integers(0, 10, 21)],
        name="b",
        region_labels={"face": np.array([1, 2])},
    )
    mesh = ControlMesh(rng.normal(size=(4, 3)), np.array([[0, 1, 2, 3]]), np.array([3]), meta={"special_cases": ["x"]})
    result = BuildResult(recipe={"template": "t", "pressure": {"lambda": float("inf")}}, bodies=[body], pressures=[], control_mesh=mesh)
    save_design(result, tmp_path / "design.npz")
    recipe, bodies, got, initial = load_design(tmp_path / "design.npz")
    assert recipe["template"] == "t" and recipe["pressure"]["lambda"] == float("inf")
    np.testing.assert_array_equal(bodies[0].vertices, body.vertices)
    np.testing.assert_array_equal(bodies[0].region_labels["face"], [1, 2])
    np.testing.assert_array_equal(got.vertices, mesh.vertices)
    assert got.meta == {"special_cases": ["x"]} and initial is None


def test_body_depth_in_surface_on_a_dome():
    """Points under a dome closed by the floor are inside; their depth is their distance to the dome."""
    from types import SimpleNamespace

    from seatkit.geometry.surface import body_depth_in_surface
    from seatkit.model import Surface

    a, b, h = 0.5, 0.4, 0.3
    xs, zs = np.linspace(-a, a, 41), np.linspace(-b, b, 33)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    Y = h * (1 - (X / a) ** 2) * (1 - (Z / b) ** 2)
    verts = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    idx = np.arange(len(verts)).reshape(X.shape)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(-1, 4)
    normals = np.tile([0.0, 1.0, 0.0], (len(verts), 1))
    dome = Surface(verts, normals, quads, 3)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.6, 0.6, 400), rng.uniform(0.001, 0.4, 400), rng.uniform(-0.5, 0.5, 400)])
    height = np.where(
        (np.abs(pts[:, 0]) < a) & (np.abs(pts[:, 2]) < b),
        h * (1 - (pts[:, 0] / a) ** 2) * (1 - (pts[:, 2] / b) ** 2),
        0.0,
    )
    inside = pts[:, 1] < height - 2e-3  # clear of the tessellation's error
    outside = pts[:, 1] > height + 2e-3
    from seatkit.geometry.surface import SurfaceQuery

    dist, _ = SurfaceQuery(dome).query(pts)
    # the deepest inside point decides; points outside never count
    got = body_depth_in_surface(dome, SimpleNamespace(vertices=pts[inside | outside]))
    assert got == pytest.approx(dist[inside].max(), abs=1e-12)
    assert body_depth_in_surface(dome, SimpleNamespace(vertices=pts[outside])) == 0.0
    # one point just under the top, 5 cm deep
    assert body_depth_in_surface(dome, SimpleNamespace(vertices=np.array([[0.0, h - 0.05, 0.0]]))) == pytest.approx(0.05, abs=2e-3)


def test_body_depth_in_surface_agrees_with_brute_force_parity():
    """The candidate filters change no answer: triangles wholly below a cell's lowest body point, points above every triangle of their cell, triangles below a point or whose plan box misses it."""
    from types import SimpleNamespace

    from seatkit.geometry.surface import SurfaceQuery, body_depth_in_surface, inside_furniture
    from seatkit.model import Surface

    rng = np.random.default_rng(7)
    # a wavy sheet with a raised back, like a seat and its back rest, over the floor
    xs, zs = np.linspace(-0.3, 0.3, 31), np.linspace(-0.3, 0.3, 31)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    Y = 0.4 + 0.05 * np.sin(8 * X) * np.cos(6 * Z) + np.where(Z < -0.15, 3.0 * (-0.15 - Z), 0.0)
    edge = (np.abs(X) > 0.299) | (np.abs(Z) > 0.299)
    Y = np.where(edge, 0.0, Y)  # the ground ring
    verts = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    idx = np.arange(len(verts)).reshape(X.shape)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(-1, 4)
    sheet = Surface(verts, np.tile([0.0, 1.0, 0.0], (len(verts), 1)), quads, 3)
    pts = np.column_stack([rng.uniform(-0.35, 0.35, 3000), rng.uniform(0.0, 0.9, 3000), rng.uniform(-0.35, 0.35, 3000)])
    # brute force: count the crossings of the ray up from each point with every triangle
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    t = verts[tris]
    q = pts + [1.2345e-9, 0.0, 2.3456e-9]
    a, b, c = t[None, :, 0], t[None, :, 1], t[None, :, 2]
    e1, e2, d = (b - a)[..., [0, 2]], (c - a)[..., [0, 2]], q[:, None, [0, 2]] - a[..., [0, 2]]
    det = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
    s = (d[..., 0] * e2[..., 1] - d[..., 1] * e2[..., 0]) / det
    r = (e1[..., 0] * d[..., 1] - e1[..., 1] * d[..., 0]) / det
    height = a[..., 1] + s * (b - a)[..., 1] + r * (c - a)[..., 1]
    crossings = ((s >= 0) & (r >= 0) & (s + r <= 1) & (height > q[:, None, 1])).sum(axis=1)
    inside = crossings % 2 == 1
    assert 100 < inside.sum() < 2900
    assert np.array_equal(inside_furniture(sheet, pts), inside)
    dist, _ = SurfaceQuery(sheet).query(pts)
    assert body_depth_in_surface(sheet, SimpleNamespace(vertices=pts)) == dist[inside].max()
    assert body_depth_in_surface(sheet, SimpleNamespace(vertices=pts[~inside])) == 0.0


def test_body_depth_in_surface_kept_is_the_depth_measured_anew():
    """An answer kept for a body and a tessellation is the one measured again, and the same surface's moved copy gets its own."""
    from types import SimpleNamespace

    from seatkit.geometry import surface as surface_module
    from seatkit.geometry.surface import body_depth_in_surface
    from seatkit.model import Surface

    xs, zs = np.linspace(-0.3, 0.3, 25), np.linspace(-0.3, 0.3, 25)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    Y = np.where((np.abs(X) > 0.299) | (np.abs(Z) > 0.299), 0.0, 0.4 + 0.05 * np.sin(8 * X) * np.cos(6 * Z))
    verts = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    idx = np.arange(len(verts)).reshape(X.shape)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(-1, 4)
    rng = np.random.default_rng(3)
    body = SimpleNamespace(vertices=np.column_stack([rng.uniform(-0.3, 0.3, 500), rng.uniform(0.0, 0.5, 500), rng.uniform(-0.3, 0.3, 500)]))
    sheet = Surface(verts, np.tile([0.0, 1.0, 0.0], (len(verts), 1)), quads, 3)
    # the same tessellation made again (other arrays, zero normals): the kept answer, which is the one measured anew
    again = Surface(verts.copy(), np.zeros_like(verts), quads.copy(), 3)
    first = body_depth_in_surface(sheet, body)
    assert first > 0.0
    assert body_depth_in_surface(again, body) == first == surface_module._body_depth_in_surface(again, body, None, 0.02)
    # lowered by 5 cm: fewer points inside, and less deep; its own answer, not the kept one
    lower = Surface(verts - [0.0, 0.05, 0.0], sheet.normals, quads, 3)
    assert body_depth_in_surface(lower, body) == surface_module._body_depth_in_surface(lower, body, None, 0.02) < first
    # the vertices inside and their distances, kept with it: those of the parity test and the surface's closest points
    inside, dist = surface_module.body_inside_furniture(again, body)
    np.testing.assert_array_equal(inside, np.flatnonzero(surface_module.inside_furniture(sheet, body.vertices)))
    np.testing.assert_array_equal(dist, surface_module.SurfaceQuery(sheet).query(body.vertices[inside])[0])
    assert dist.max() == first
