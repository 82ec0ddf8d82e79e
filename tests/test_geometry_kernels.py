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
