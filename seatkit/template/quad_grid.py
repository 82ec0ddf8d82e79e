"""Structured quad grids with a ground ring: the shape of every seat cage.

A cage of ``r x c`` faces has ``(r + 1) x (c + 1)`` vertices, numbered row
by row (``i * (c + 1) + j``); its outermost ring of vertices is the ground
border. Rows run along +Z (front of the body is +Z), columns along +X, and
faces are ordered so that their normals point up (+Y), at the body.
"""

from __future__ import annotations

import numpy as np

__all__ = ["grid_faces", "grid_ring"]


def grid_faces(rows: int, cols: int) -> np.ndarray:
    """Quads of a ``rows x cols`` face grid.

    Parameters
    ----------
    rows, cols : int
        Number of faces along the two grid directions.

    Returns
    -------
    faces : (rows * cols, 4) int64
        Counter-clockwise seen from +Y when row ``i`` grows along +Z and
        column ``j`` along +X.
    """
    stride = cols + 1
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = (i * stride + j).ravel()
    return np.column_stack([a, a + stride, a + stride + 1, a + 1]).astype(np.int64)


def grid_ring(rows: int, cols: int, ring: int = 0) -> np.ndarray:
    """Boolean mask of the vertices of ring ``ring`` (0 = outermost).

    Parameters
    ----------
    rows, cols : int
        Face counts of the grid.
    ring : int

    Returns
    -------
    mask : ((rows + 1) * (cols + 1),) bool
    """
    i, j = np.meshgrid(np.arange(rows + 1), np.arange(cols + 1), indexing="ij")
    depth = np.minimum(np.minimum(i, rows - i), np.minimum(j, cols - j))
    return (depth == ring).ravel()
