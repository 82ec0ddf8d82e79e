"""Signed distance to a body's skin (seatkit.geometry.skin), checked against brute force and open3d."""

import numpy as np
import pytest
import trimesh

from seatkit.geometry.closest import closest_point_on_triangles
from seatkit.geometry.skin import SkinDistance


def _brute_distance(vertices, faces, points):
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    out = np.empty(len(points))
    for i, p in enumerate(points):
        q, _ = closest_point_on_triangles(p[None, :], a, b, c)
        out[i] = np.sqrt(((q - p) ** 2).sum(axis=1).min())
    return out


def _occupancy(v, f, points):
    """Inside a closed mesh by open3d's ray casting (an independent check)."""
    o3d = pytest.importorskip("open3d")
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.int32))))
    return scene.compute_occupancy(o3d.core.Tensor(points.astype(np.float32)), nsamples=3).numpy() > 0.5


def test_sphere_depth_matches_brute_force_and_sign():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(300, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radii = rng.uniform(0.09, 0.11, 300)  # within SkinDistance.EXACT_WITHIN of the skin
    points = directions * radii[:, None]
    skin = SkinDistance(v, f)
    depth, closest, out = skin.query(points)
    truth = _brute_distance(v, f, points)
    inside = _occupancy(v, f, points)
    assert np.allclose(np.abs(depth), truth, atol=1e-9)
    assert np.array_equal(depth > 0, inside)
    # the way out points away from the centre, and from the point to its closest skin point outside
    assert np.all(np.einsum("ij,ij->i", out, directions) > 0.9)
    assert np.allclose(np.linalg.norm(closest - points, axis=1), truth, atol=1e-9)
    # winding numbers: 1 inside, 0 outside
    w = skin.winding_numbers(points[:40])
    assert np.allclose(w, inside[:40].astype(float), atol=1e-6)
    # farther out, the nearest vertex's estimate: right side, distance within a few mm
    far = directions[:50] * 0.13
    d_far, _, _ = skin.query(far)
    assert np.all(d_far < 0)
    assert np.allclose(-d_far, _brute_distance(v, f, far), atol=3e-3)


def _fine(mesh, edge=0.01):
    """A mesh tessellated like a body's skin (edges of about a centimetre)."""
    v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=edge)
    return trimesh.Trimesh(v, f)


def _two_boxes():
    """Two boxes that overlap, as one self-intersecting skin with centimetre edges (vertices, faces)."""
    a = _fine(trimesh.creation.box(extents=(0.2, 0.1, 0.1)))
    b = _fine(trimesh.creation.box(extents=(0.1, 0.1, 0.3)))
    b.apply_translation((0.12, 0.0, 0.0))
    return np.vstack([a.vertices, b.vertices]), np.vstack([a.faces, b.faces + len(a.vertices)])


def test_crease_between_overlapping_parts_is_settled_by_the_winding_number():
    # two boxes that overlap, as one self-intersecting skin (a hand sunk into a thigh)
    v, f = _two_boxes()
    skin = SkinDistance(v, f)
    # inside box a, but outside box b, and nearest to b's skin: a local sign calls it outside
    p = np.array([[0.064, 0.0, 0.0]])
    depth, _, _ = skin.query(p)
    assert depth[0] < 0  # the local test is wrong here ...
    assert skin.winding_numbers(p)[0] == pytest.approx(1.0)  # ... the winding number is not
    # in the overlap of both parts: winding number 2
    assert skin.winding_numbers(np.array([[0.09, 0.0, 0.0]]))[0] == pytest.approx(2.0)
    # max_depth reports only confirmed points: a point outside both boxes
    # that a local test might call inside never counts
    outside = np.array([[0.0, 0.2, 0.0], [0.3, 0.0, 0.0]])
    assert skin.max_depth(outside) == 0.0
    assert skin.max_depth(np.array([[0.0, 0.0, 0.0]])) == pytest.approx(0.05)


def test_body_depth_agrees_with_open3d_and_the_winding_number():
    o3d = pytest.importorskip("open3d")
    from seatkit.body import load_rig

    body = load_rig("default-male")  # the rest pose: the skin does not touch itself
    rng = np.random.default_rng(1)
    points = body.vertices[rng.integers(0, len(body.vertices), 3000)] + rng.normal(0.0, 0.004, (3000, 3))
    skin = SkinDistance(body.vertices, body.faces)
    depth, _, _ = skin.query(points)
    mesh = o3d.t.geometry.TriangleMesh(
        o3d.core.Tensor(body.vertices.astype(np.float32)), o3d.core.Tensor(body.faces.astype(np.int32))
    )
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(mesh)
    unsigned = scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()
    err = np.abs(np.abs(depth) - unsigned)
    # open3d computes in float32: agreement to its precision, nearly everywhere
    # (the candidates are the triangles around the two nearest vertices)
    assert np.mean(err < 1e-5) > 0.995
    # where the nearest vertices miss the closest triangle (between fingers)
    # the distance found is to a farther triangle: never smaller than the truth
    assert np.all(np.abs(depth) >= unsigned - 1e-5)
    assert err.max() < 5e-3
    # inside or outside as the winding number says
    w = skin.winding_numbers(points[:200])
    assert np.array_equal(depth[:200] > 0, w > 0.5)


def test_of_caches_per_array():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    v, f = np.array(sphere.vertices), np.array(sphere.faces)
    first = SkinDistance.of(v, f)
    assert SkinDistance.of(v, f) is first
    other = SkinDistance.of(v.copy(), f)
    assert other is not first
    assert np.array_equal(other.query(v[:5] * 1.1)[0], first.query(v[:5] * 1.1)[0])


def test_degenerate_triangles_and_stray_vertices_do_not_poison_answers():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    v, f = np.asarray(sphere.vertices, dtype=float), np.asarray(sphere.faces)
    rng = np.random.default_rng(2)
    d = rng.normal(size=(500, 3))
    points = 0.1 * (1 + rng.uniform(-0.08, 0.08, 500))[:, None] * d / np.linalg.norm(d, axis=1, keepdims=True)
    clean = SkinDistance(v, f).query(points)[0]
    # a face with two coincident corners (a == b), and two vertices no face uses, right next to the points
    stray = np.array([[0.105, 0.0, 0.0], [0.106, 0.001, 0.0]])
    v2 = np.vstack([v, stray])
    f2 = np.vstack([f, [f[0, 0], f[0, 0], f[0, 1]]])
    depth, closest, out = SkinDistance(v2, f2).query(np.vstack([points, [[0.11, 0.0, 0.0]]]))
    assert np.all(np.isfinite(depth)) and np.all(np.isfinite(closest)) and np.all(np.isfinite(out))
    assert np.allclose(depth[:-1], clean, atol=1e-12)
    # the point by the stray vertices is answered from the skin, not from them
    assert depth[-1] < -0.005


def test_points_in_open_space_under_a_self_touching_body_are_outside():
    # crossed legs: each thigh's skin runs inside the other; below the crotch
    # the nearest skin is buried skin facing up, whose side calls the open
    # space under the body "inside" (40 cm deep, as the flat-patch baseline
    # saw it)
    from seatkit.pipeline import make_bodies
    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import load_recipe

    registry = get_plugin_manager(autoload=False).registry
    recipe, _ = load_recipe({"template": "chair", "bodies": [{"model": "default-male", "pose": "crossed-legs-ankles"}]})
    body = make_bodies(recipe, registry)[0]
    skin = SkinDistance(body.vertices, body.faces)
    x, y, z = np.meshgrid(np.linspace(-0.06, 0.06, 7), np.linspace(0.0, 0.3, 16), np.linspace(0.0, 0.12, 7), indexing="ij")
    column = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    points = np.vstack([[[-0.01303357, 0.01531762, 0.06865703]], column])
    assert skin.winding_numbers(points[:1])[0] == pytest.approx(0.0, abs=1e-6)
    depth, closest, out = skin.query(points)
    # the side: inside only where the winding number says so
    called_inside = np.flatnonzero(depth > 0)
    assert np.all(skin.winding_numbers(points[called_inside]) > 0.5)
    # the distance is still the one to the closest skin found, and the way out leads away from it
    assert depth[0] == pytest.approx(-np.linalg.norm(points[0] - closest[0]))
    assert depth[0] < -0.1
    assert np.allclose(out[0], (points[0] - closest[0]) / np.linalg.norm(points[0] - closest[0]))
    # far outside the skin's box, and in the open space between the box and the body: outside
    assert np.all(skin._in_open_space(np.array([[0.0, -1.0, 0.0], [5.0, 5.0, 5.0], points[0]])))
    assert not np.any(skin._in_open_space(body.vertices[::50]))  # the skin's own cells are never open


def test_clear_of_is_a_lower_bound_on_the_distance_outside():
    # a body-like skin (two overlapping boxes, edges of a centimetre) and
    # points all around it: clear_of never exceeds the true distance, is 0
    # for points inside, and is positive for most points a few cells away
    v, f = _two_boxes()
    skin = SkinDistance(v, f)
    rng = np.random.default_rng(3)
    points = rng.uniform((-0.25, -0.15, -0.3), (0.3, 0.15, 0.3), size=(1500, 3))
    truth = _brute_distance(v, f, points)
    inside = skin.winding_numbers(points) > 0.5
    clear = skin.clear_of(points)
    assert np.all(clear >= 0.0)
    assert np.all(clear <= truth + 1e-12)
    assert np.all(clear[inside] == 0.0)
    # it is not vacuous: points more than 3 cells from the skin get a bound of at least a quarter of their distance
    far = ~inside & (truth > 3 * SkinDistance.OPEN_SPACE_CELL)
    assert far.sum() > 100 and np.all(clear[far] > truth[far] / 4)
    # the fit's use of it: the query says the same where the bound lets it be asked, and the others are farther out
    from seatkit.refine.ccfit import skin_depth, skin_depth_near

    near = 0.012
    d_all, _, _ = skin_depth([skin], points)
    d_near, _, _ = skin_depth_near([skin], points, near)
    asked = clear < near
    assert np.array_equal(d_near[asked], d_all[asked])
    assert np.all(d_near[~asked] <= -near) and np.all(d_all[~asked] <= -near)
    # a clearance beyond the exact query's reach (above 15 mm) asks every point, as before the bound
    d_wide, _, _ = skin_depth_near([skin], points, 2 * SkinDistance.EXACT_WITHIN)
    assert np.array_equal(d_wide, d_all)
    # max_depth skips the points in open space and answers as before
    assert skin.max_depth(points) == pytest.approx(float(np.max(np.where(inside, truth, 0.0))), abs=1e-9)


def test_row_norms_is_numpys_norm_to_the_bit():
    # the queries' fast row lengths must not change a single answer: the same
    # values as np.linalg.norm along the last axis, whatever the layout
    from seatkit.geometry.closest import row_norms

    rng = np.random.default_rng(7)
    for n in (1, 3, 8, 17, 1000):
        a = rng.normal(size=(n, 3)) * rng.choice([1e-9, 1.0, 1e4], size=(n, 1))
        for x in (a, np.asfortranarray(a), rng.normal(size=(n, 6))[:, ::2], rng.normal(size=(n, 4, 3))):
            assert np.array_equal(row_norms(x), np.linalg.norm(x, axis=-1))
