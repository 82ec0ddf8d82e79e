"""Retargeting maths: a skeleton's axes and the rotations that carry its pose onto a rig.

:func:`check_axes` refuses a skeleton whose body axes are undefined (hips
without width, a head on the hips); :func:`facing_rotation` is the rotation
that takes a skeleton's left and up directions to seatkit's +X and +Y (the
body facing +Z), snapped to an axis permutation when the file's axes are
merely permuted; :func:`swing` is the smallest rotation turning one bone
direction onto another (the rest-pose corrections ``C_s`` and chord
rotations ``S_s`` of :mod:`seatkit.body.bvh`); :data:`CHAIN_CHILD` is each
segment's child along the main chain, whose joint gives the bone direction.
The BVH reader, the glTF reader and the anny plugin share them.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from seatkit.errors import InputError

__all__ = ["CHAIN_CHILD", "swing", "check_axes", "facing_rotation"]

#: The child along the main chain of each segment (-1 for end segments).
CHAIN_CHILD: np.ndarray = np.array(
    [7, 2, 3, -1, 5, 6, -1, 8, 9, 10, 11, 12, -1, 14, 15, 16, -1, 18, 19, 20, -1], dtype=np.int64
)

_EPS = 1e-12


def swing(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The smallest rotation turning direction ``u`` onto direction ``v``.

    Parameters
    ----------
    u, v : (3,) float64
        Non-zero vectors (a zero one gives the identity).

    Returns
    -------
    (3, 3) float64
    """
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if nu < _EPS or nv < _EPS:
        return np.eye(3)
    a, b = u / nu, v / nv
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        # opposite: half turn about any axis perpendicular to a
        perp = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        return Rotation.from_rotvec(np.pi * perp / np.linalg.norm(perp)).as_matrix()
    return Rotation.from_rotvec(axis / s * np.arctan2(s, c)).as_matrix()


def check_axes(left: np.ndarray, up: np.ndarray, extent: float, where: str) -> None:
    """Refuse a skeleton whose hips have no width or whose head sits on its hips.

    ``left`` (right hip to left hip) and ``up`` (hips to head) must be finite,
    at least a thousandth of the skeleton's ``extent`` long and not parallel
    (within 5 degrees): otherwise the body's axes, and every rotation derived
    from them, are undefined.

    Raises
    ------
    InputError
        Naming ``where`` (the file) and what is degenerate.
    """
    left, up = np.asarray(left, dtype=np.float64), np.asarray(up, dtype=np.float64)
    if not (np.isfinite(left).all() and np.isfinite(up).all() and np.isfinite(extent) and extent > 0):
        msg = f"{where}: the skeleton's joint positions are not finite"
        raise InputError(msg)
    nl, nu = float(np.linalg.norm(left)), float(np.linalg.norm(up))
    if nl < 1e-3 * extent:
        msg = f"{where}: degenerate skeleton: the left and right hip joints coincide (the body has no left-right axis)"
        raise InputError(msg)
    if nu < 1e-3 * extent:
        msg = f"{where}: degenerate skeleton: the head joint sits on the hips (the body has no up axis)"
        raise InputError(msg)
    if abs(float(left @ up)) > np.cos(np.radians(5.0)) * nl * nu:
        msg = f"{where}: degenerate skeleton: the hips' left-right axis is parallel to the hips-to-head axis"
        raise InputError(msg)


def facing_rotation(left: np.ndarray, up: np.ndarray, *, snap: bool = True) -> np.ndarray:
    """Rotation taking a skeleton's left and up directions to seatkit's +X and +Y.

    Parameters
    ----------
    left : (3,) float64
        Right hip to left hip (the body's left), any length.
    up : (3,) float64
        Hips to head.
    snap : bool
        Round to the nearest axis-aligned rotation (a signed permutation), so
        that a file whose axes are merely permuted is converted exactly.

    Returns
    -------
    A : (3, 3) float64
        ``A @ up`` is along +Y, ``A @ left`` along +X, the body faces +Z.
    """
    u = up / np.linalg.norm(up)
    lft = left - (left @ u) * u
    lft = lft / np.linalg.norm(lft)
    fwd = np.cross(lft, u)
    A = np.stack([lft, u, fwd])  # rows: where each seatkit axis comes from
    if snap:
        snapped = np.zeros((3, 3))
        cols = np.argmax(np.abs(A), axis=1)
        snapped[np.arange(3), cols] = np.sign(A[np.arange(3), cols])
        if len(set(cols.tolist())) == 3 and np.linalg.det(snapped) > 0.5:
            return snapped
    return A
