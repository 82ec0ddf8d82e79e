"""Quality measures of a quad cage: interior angles, planarity, regularity.

These are the figures the ``optimize`` refiner reports before and after it
runs (in ``ControlMesh.meta["optimize"]``), and the quantities its angle
terms act on.

Definitions (``f`` quads, corners in face order):

- interior angle ``alpha`` of corner ``k`` of a face: the angle between the
  edges to the previous and the next corner, in [0, pi];
- planarity of a face: the distance between its two diagonals divided by
  their mean length (0 for a planar quad; the usual measure of architectural
  geometry, scale free);
- regularity of a face: the mean of ``|alpha - pi/2|`` over its corners
  (0 for a rectangle). The paper's "regular faces" term
  ``(sum alpha - 2 pi)^2`` vanishes for *every* planar convex quad, so it
  measures non-planarity and folding; ``|alpha - pi/2|`` measures what a
  reader calls regular.
"""

from __future__ import annotations

import numpy as np

__all__ = ["face_angles", "face_planarity", "cage_quality", "mesh_edges"]


def mesh_edges(faces: np.ndarray) -> np.ndarray:
    """Unique undirected edges of a polygon mesh.

    Parameters
    ----------
    faces : (f, k) int64
        Polygons with ``k`` corners each.

    Returns
    -------
    edges : (e, 2) int64
        Vertex pairs, smaller index first, sorted lexicographically.
    """
    faces = np.asarray(faces, dtype=np.int64)
    # every consecutive corner pair (k -> k+1) of every face
    pairs = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    pairs.sort(axis=1)
    return np.unique(pairs, axis=0)


def face_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Interior angle at every corner of every face.

    Parameters
    ----------
    vertices : (v, 3) float64
    faces : (f, k) int64

    Returns
    -------
    angles : (f, k) float64
        Angle between the edges to the previous and next corner, rad.
    """
    corner = vertices[faces]
    to_prev = np.roll(corner, 1, axis=1) - corner
    to_next = np.roll(corner, -1, axis=1) - corner
    # atan2(|a x b|, a . b) is accurate near 0 and pi, unlike arccos
    sin_part = np.linalg.norm(np.cross(to_prev, to_next), axis=-1)
    cos_part = np.einsum("fkc,fkc->fk", to_prev, to_next)
    return np.arctan2(sin_part, cos_part)


def face_planarity(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Distance between the diagonals of each quad over their mean length.

    Parameters
    ----------
    vertices : (v, 3) float64
    faces : (f, 4) int64

    Returns
    -------
    planarity : (f,) float64
        0 for a planar face.
    """
    a, b, c, d = (vertices[faces[:, k]] for k in range(4))
    diag1, diag2 = c - a, d - b
    normal = np.cross(diag1, diag2)
    norm = np.linalg.norm(normal, axis=1)
    # distance between the two (infinite) diagonal lines; parallel diagonals
    # (a degenerate face) fall back to the distance of b from line a-c
    safe = norm > 1e-15 * (np.linalg.norm(diag1, axis=1) * np.linalg.norm(diag2, axis=1) + 1e-300)
    dist = np.where(
        safe,
        np.abs(np.einsum("fc,fc->f", b - a, normal)) / np.where(safe, norm, 1.0),
        np.linalg.norm(np.cross(b - a, diag1), axis=1) / np.maximum(np.linalg.norm(diag1, axis=1), 1e-300),
    )
    mean_diag = 0.5 * (np.linalg.norm(diag1, axis=1) + np.linalg.norm(diag2, axis=1))
    return dist / np.maximum(mean_diag, 1e-300)


def cage_quality(vertices: np.ndarray, faces: np.ndarray) -> dict[str, float]:
    """Summary quality figures of a quad cage.

    Parameters
    ----------
    vertices : (v, 3) float64
    faces : (f, 4) int64

    Returns
    -------
    dict
        ``planarity_mean``, ``planarity_max`` (dimensionless),
        ``min_angle_deg``, ``max_angle_deg``, ``regularity_deg`` (mean
        ``|alpha - 90 deg|``), ``angle_sum_error_deg`` (mean
        ``|sum alpha - 360 deg|`` per face), ``min_edge_length`` (m).
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    angles = face_angles(vertices, faces)
    planarity = face_planarity(vertices, faces)
    edges = mesh_edges(faces)
    lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    return {
        "planarity_mean": float(planarity.mean()),
        "planarity_max": float(planarity.max()),
        "min_angle_deg": float(np.degrees(angles.min())),
        "max_angle_deg": float(np.degrees(angles.max())),
        "regularity_deg": float(np.degrees(np.abs(angles - 0.5 * np.pi).mean())),
        "angle_sum_error_deg": float(np.degrees(np.abs(angles.sum(axis=1) - 2.0 * np.pi).mean())),
        "min_edge_length": float(lengths.min()),
    }
