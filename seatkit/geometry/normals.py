"""Normals of triangle meshes and quad cages: the one implementation the library uses.

:func:`face_normals` gives unit triangle normals and areas;
:func:`vertex_normals` the area-weighted outward vertex normals of a
triangle mesh (the sum of the incident triangles' un-normalised cross
products, so the weighting by area comes for free), which the pressure
assembly, the template's checks, the Catmull-Clark fit and the pictures all
use; :func:`quad_vertex_normals` the normals of a quad cage's vertices (the
mean of the incident quads' unit diagonal-cross normals), which the
template's clearance step pushes faces along.
"""

from __future__ import annotations

import numpy as np

from seatkit.cache import IdentityCache

__all__ = ["face_normals", "vertex_normals", "kept_vertex_normals", "quad_vertex_normals", "sum_rows_at"]


def sum_rows_at(n: int, index: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(n, d) float64: the rows of ``values`` (k, d) summed into the rows ``index`` (k,) name.

    ``np.add.at(out, index, values)`` on zeros, to the bit (each row's sum
    is taken in the order of ``index``), about 6 times faster: one
    ``np.bincount`` per column. Several ``np.add.at`` passes in turn are one
    call with their indices and values concatenated in that order.
    """
    index = np.asarray(index, dtype=np.int64).ravel()
    values = np.asarray(values, dtype=np.float64).reshape(len(index), -1)
    out = np.empty((n, values.shape[1]))
    for d in range(values.shape[1]):
        out[:, d] = np.bincount(index, weights=values[:, d], minlength=n)
    return out


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals and areas of the triangles.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
        Counter-clockwise seen from outside.

    Returns
    -------
    normals : (m, 3) float64
        Unit outward normals (zero for degenerate triangles).
    areas : (m,) float64
        Triangle areas, m^2.
    """
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    safe = np.where(double_area > 0, double_area, 1.0)
    return cross / safe[:, None], 0.5 * double_area


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted outward unit vertex normals of a triangle mesh.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64

    Returns
    -------
    normals : (n, 3) float64
        Unit normals; zero rows for vertices in no (non-degenerate) triangle.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    tri = vertices[faces]
    # un-normalised face normal = 2 * area * unit normal: area weighting for free
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    # each corner's triangles in turn, as np.add.at corner by corner would
    summed = sum_rows_at(len(vertices), faces.T, np.concatenate([cross, cross, cross]))
    length = np.linalg.norm(summed, axis=1)
    return summed / np.where(length > 0, length, 1.0)[:, None]


#: :func:`kept_vertex_normals` by the vertex and face arrays (their identity).
_KEPT = IdentityCache(maxsize=8)


def kept_vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """:func:`vertex_normals`, computed once for the last few vertex and face arrays in this process (read-only).

    A build asks for a body's normals in its importance solve, its
    template's clearance and its evaluation: the same arrays each time.
    """

    def make():
        normals = vertex_normals(vertices, faces)
        normals.flags.writeable = False
        return normals

    return _KEPT.get((vertices, faces), make)


def quad_vertex_normals(vertices: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(v, 3) float64 unit normals of a quad cage (mean of the faces' diagonal-cross normals)."""
    fn = np.cross(vertices[quads[:, 2]] - vertices[quads[:, 0]], vertices[quads[:, 3]] - vertices[quads[:, 1]])
    fn = fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-12)
    vn = np.zeros_like(vertices)
    for i in range(4):
        np.add.at(vn, quads[:, i], fn)
    return vn / np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-12)
