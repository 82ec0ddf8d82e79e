"""The shared geometry kernels: candidate triangles of a closest-point search, and sums into rows."""

import numpy as np
import trimesh

from seatkit.geometry.closest import distinct_ring_triangles, vertex_triangle_rings
from seatkit.geometry.normals import sum_rows_at, vertex_normals


def test_distinct_ring_triangles_lists_each_triangle_around_the_vertices_once_in_first_order():
    mesh = trimesh.creation.icosphere(subdivisions=2)
    faces = np.asarray(mesh.faces)
    rings = vertex_triangle_rings(faces, len(mesh.vertices))
    rng = np.random.default_rng(3)
    near = rng.integers(0, len(mesh.vertices), (500, 3))
    near[:200, 1] = faces[rng.integers(0, len(faces), 200), 0]  # some neighbours: shared triangles
    near[:200, 0] = faces[rng.integers(0, len(faces), 200), 1]
    seen_rows = []
    for rows, cand in distinct_ring_triangles(rings, near):
        assert cand.shape[0] == rows.size
        for row, listed in zip(rows, cand):
            full = rings[near[row]].ravel()
            first = list(dict.fromkeys(int(t) for t in full if t >= 0))  # distinct, in first-occurrence order
            assert [int(t) for t in listed if t >= 0] == first
            assert np.all(listed[len(first) :] == -1)
        seen_rows.append(rows)
    assert np.array_equal(np.sort(np.concatenate(seen_rows)), np.arange(len(near)))


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
