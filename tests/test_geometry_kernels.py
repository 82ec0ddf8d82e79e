"""The shared geometry kernels: sums into rows, vertex normals, closest points of large batches."""

import numpy as np
import trimesh

from seatkit.geometry.normals import sum_rows_at, vertex_normals


def test_sum_rows_at_is_np_add_at_to_the_bit():
    rng = np.random.default_rng(4)
    index = rng.integers(0, 50, (3, 400))
    values = rng.normal(size=(3, 400, 3)) * 10.0 ** rng.integers(-8, 8, (3, 400, 1))
    expected = np.zeros((60, 3))
    for k in range(3):  # pass by pass, as a caller with np.add.at would
        np.add.at(expected, index[k], values[k])
    assert np.array_equal(sum_rows_at(60, index, values.reshape(-1, 3)), expected)


def test_vertex_normals_are_unit_and_point_outward_on_a_sphere():
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.2)
    v = np.asarray(mesh.vertices)
    n = vertex_normals(v, np.asarray(mesh.faces))
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.all(np.einsum("ij,ij->i", n, v / np.linalg.norm(v, axis=1, keepdims=True)) > 0.99)


def test_a_large_batch_gets_the_answers_each_point_gets_alone():
    """Skin and surface queries work through large batches in blocks: a point's answer does not depend on its batch."""
    from seatkit.geometry.skin import SkinDistance
    from seatkit.geometry.surface import SurfaceQuery
    from seatkit.model import Surface

    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    skin = SkinDistance(np.asarray(sphere.vertices), np.asarray(sphere.faces))
    rng = np.random.default_rng(5)
    points = rng.normal(size=(2 * SkinDistance._BLOCK + 37, 3)) * 0.06
    whole = skin.query(points)
    for lo in range(0, len(points), 97):
        part = skin.query(points[lo : lo + 97])
        assert all(np.array_equal(a[lo : lo + 97], b) for a, b in zip(whole, part))

    grid = np.stack(np.meshgrid(np.linspace(0, 1, 12), np.linspace(0, 1, 12), indexing="ij"), axis=-1).reshape(-1, 2)
    verts = np.column_stack([grid[:, 0], 0.1 * np.sin(3 * grid[:, 1]), grid[:, 1]])
    ij = np.arange(144).reshape(12, 12)
    quads = np.stack([ij[:-1, :-1], ij[1:, :-1], ij[1:, 1:], ij[:-1, 1:]], axis=-1).reshape(-1, 4)
    normals = np.tile([0.0, 1.0, 0.0], (len(verts), 1))
    query = SurfaceQuery(Surface(verts, normals, quads, 0))
    points = rng.uniform([0, -0.2, 0], [1, 0.3, 1], (3 * SurfaceQuery._BLOCK + 11, 3))
    whole = query.closest_normals(points)
    for lo in range(0, len(points), 101):
        part = query.closest_normals(points[lo : lo + 101])
        assert all(np.array_equal(a[lo : lo + 101], b, equal_nan=True) for a, b in zip(whole, part))


def _search_every_slot(skin, points, cand):
    """The closest of the candidate triangles with every slot searched (padding at infinity), the first of equals."""
    from seatkit.geometry.closest import closest_barycentric

    valid = cand >= 0
    t = np.where(valid, cand, 0)
    g = np.take(skin._table, t, axis=0)
    ap = points[:, None, :] - g[..., 0:3]
    d1 = np.einsum("kci,kci->kc", g[..., 3:6], ap)
    d2 = np.einsum("kci,kci->kc", g[..., 6:9], ap)
    d00, d01, d11 = g[..., 9], g[..., 10], g[..., 11]
    u, v, w = closest_barycentric(d1, d2, d00, d01, d11)
    d2sq = np.einsum("kci,kci->kc", ap, ap) - 2.0 * (v * d1 + w * d2) + v * v * d00 + 2.0 * v * w * d01 + w * w * d11
    d2sq = np.where(valid & np.isfinite(d2sq), np.maximum(d2sq, 0.0), np.inf)
    best = np.argmin(d2sq, axis=1)
    rows = np.arange(len(points))
    return t[rows, best], np.stack([u[rows, best], v[rows, best], w[rows, best]], axis=1)


def test_the_skin_search_skips_padding_and_repeats_to_the_bit():
    """The rings of a point's nearest vertices share triangles and end in padding: the search skips both and finds what searching every slot finds."""
    from seatkit.geometry.skin import SkinDistance

    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    skin = SkinDistance(np.asarray(sphere.vertices), np.asarray(sphere.faces))
    rng = np.random.default_rng(8)
    # near the skin, on its vertices and edge midpoints (equally near triangles), and outside it
    v = skin.vertices
    e = skin.faces[:, :2]
    points = np.concatenate([rng.normal(size=(300, 3)) * 0.06, v[:60], 0.5 * (v[e[:60, 0]] + v[e[:60, 1]]), v[:60] * 1.02])
    for k in (1, 2, 3):
        _, near = skin.tree.query(points, k=k)
        cand = np.take(skin.rings, skin._used[near.reshape(len(points), -1)], axis=0).reshape(len(points), -1)
        assert (cand >= 0).sum() > np.unique(cand[cand >= 0]).size  # repeats and padding to skip
        tri, bary = skin._nearest_triangle(points, cand)
        ref_tri, ref_bary = _search_every_slot(skin, points, cand)
        assert np.array_equal(tri, ref_tri)
        assert np.array_equal(bary, ref_bary)


def test_a_few_points_get_the_answers_they_get_in_a_large_batch():
    """A SurfaceQuery asked about a few points searches their own vertices' rings: the same answers, to the bit."""
    from seatkit.geometry.surface import SurfaceQuery
    from seatkit.model import Surface

    n = 40
    grid = np.stack(np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij"), axis=-1).reshape(-1, 2)
    verts = np.column_stack([grid[:, 0], 0.1 * np.sin(3 * grid[:, 1]) * np.cos(2 * grid[:, 0]), grid[:, 1]])
    ij = np.arange(n * n).reshape(n, n)
    quads = np.stack([ij[:-1, :-1], ij[1:, :-1], ij[1:, 1:], ij[:-1, 1:]], axis=-1).reshape(-1, 4)
    rng = np.random.default_rng(9)
    normals = np.tile([0.0, 1.0, 0.0], (len(verts), 1)) + rng.normal(scale=0.3, size=(len(verts), 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)  # which triangle a point's nearest is on shows in its normal
    surface = Surface(verts, normals, quads, 0)
    points = np.concatenate([rng.uniform([0, -0.2, 0], [1, 0.3, 1], (400, 3)), verts[:50], verts[quads[:50]].mean(axis=1)])
    whole = SurfaceQuery(surface).closest_normals(points)
    for lo in range(0, len(points), 3):
        few = SurfaceQuery(surface).closest_normals(points[lo : lo + 3])  # a fresh query: nothing built yet
        assert all(np.array_equal(a[lo : lo + 3], b, equal_nan=True) for a, b in zip(whole, few))
    dist, side, normal = SurfaceQuery(surface).closest_normals(points[:4], within=0.05)
    searched = np.isfinite(dist)  # the others are farther than that
    assert 0 < searched.sum() < 4
    assert np.array_equal(dist[searched], whole[0][:4][searched]) and np.array_equal(normal[searched], whole[2][:4][searched])
