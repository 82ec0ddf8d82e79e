"""Per-vertex areas of a triangle mesh (its normals: :mod:`seatkit.geometry.normals`).

The paper divides each vertex's reaction by its Voronoi area (Eq. 4) so that
the result does not depend on mesh resolution. We use the *mixed* Voronoi
area of Meyer, Desbrun, Schroeder and Barr (2003, "Discrete
Differential-Geometry Operators for Triangulated 2-Manifolds", Fig. 4): the
true Voronoi region inside non-obtuse triangles and the barycentric-style
split (half / quarter of the triangle) inside obtuse ones, so the areas are
positive and sum exactly to the surface area.
"""

from __future__ import annotations

import numpy as np

__all__ = ["mixed_voronoi_areas"]


def mixed_voronoi_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Mixed Voronoi area of every vertex (Meyer et al. 2003).

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64

    Returns
    -------
    areas : (n,) float64
        Area attributed to each vertex, m^2; they sum to the surface area.
        Vertices in no triangle get 0.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    tri = vertices[faces]  # (m, 3, 3): corner k of each triangle
    # edge opposite corner k: from corner k+1 to corner k+2
    e_opp = np.roll(tri, -2, axis=1) - np.roll(tri, -1, axis=1)  # (m, 3, 3)
    sq_len = np.einsum("mkd,mkd->mk", e_opp, e_opp)  # |opposite edge|^2
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    tri_area = 0.5 * double_area
    # cot of the angle at corner k: dot of the two edges leaving k / |cross|
    to_next = np.roll(tri, -1, axis=1) - tri
    to_prev = np.roll(tri, -2, axis=1) - tri
    dots = np.einsum("mkd,mkd->mk", to_next, to_prev)
    safe = np.where(double_area > 0, double_area, 1.0)[:, None]
    cot = dots / safe
    # Voronoi share of corner k: (|e_{k+1}|^2 cot_{k+1} + |e_{k+2}|^2 cot_{k+2}) / 8,
    # where e_i is the edge opposite corner i (each edge at corner k is opposite
    # one of the two other corners)
    term = sq_len * cot
    voronoi = (np.roll(term, -1, axis=1) + np.roll(term, -2, axis=1)) / 8.0
    obtuse_at = dots < 0  # (m, 3) angle at corner k is obtuse
    any_obtuse = obtuse_at.any(axis=1)
    share = np.where(
        any_obtuse[:, None],
        np.where(obtuse_at, 0.5, 0.25) * tri_area[:, None],
        voronoi,
    )
    share[double_area == 0] = 0.0
    areas = np.zeros(len(vertices))
    for corner in range(3):
        np.add.at(areas, faces[:, corner], share[:, corner])
    return areas
