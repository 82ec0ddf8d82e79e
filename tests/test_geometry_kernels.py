"""The shared geometry kernels: sums into rows, vertex normals, closest points in blocks."""

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
