"""Tangent frames and the paper's local reaction weights (Eqs. 2-3).

Every contact vertex gets a frame (n, t1, t2):

- ``n`` is the *inward* unit normal (minus the outward surface normal): the
  direction a support pushes the body. The normal component of a reaction is
  ``>= 0`` along it.
- ``t1`` is the "downhill" direction: world down (-Y) projected onto the
  tangent plane and normalised. Gravity acting on an isolated vertex then
  has no ``t2`` component, so the weights below do not depend on an
  arbitrary choice of tangent. Where the tangent plane is horizontal
  (downhill undefined) ``t1`` is +Z projected onto the plane (or +X).
- ``t2 = n x t1``, so the frame is right-handed.

Local reaction weights (Eqs. 2-3): a unit load ``f = (0, -1, 0)`` on an
isolated vertex is split into its normal and tangential parts, the support
answers with ``r_n = -f_n`` and friction ``r_t`` clipped to ``mu |f_n|``,
and the weights are the inverse magnitudes ``w_n = 1/|r|``,
``w_t1 = 1/|r_n + r_t1|``, ``w_t2 = 1/|r_n + r_t2|``.

The paper leaves two cases open, which we close as follows:

- A support can only *push*: where the outward normal points up or sideways
  (``c = -n_out . Y <= 0``: top of the head, shoulders, vertical flanks) the
  support under the vertex cannot carry its load, ``r = 0`` and the weights
  are infinite. We use ``|f_n| = max(c, 0)``.
- Infinite (and nearly infinite) weights are capped at ``cap``
  (default :data:`DEFAULT_WEIGHT_CAP` = 1000): ``w = 1 / max(|.|, 1/cap)``.
  Such a vertex can still carry a reaction, but it costs ``cap^2 = 1e6``
  times as much per newton as a vertex of a horizontal seat, so in practice
  it carries only what no other contact can. Dropping those vertices instead
  would make some contact sets (a vertical backrest) infeasible.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEFAULT_WEIGHT_CAP", "tangent_frames", "local_reaction_weights"]

#: Largest local reaction weight (dimensionless); caps the paper's 1/|r| where
#: the surface cannot hold a downward load.
DEFAULT_WEIGHT_CAP = 1.0e3


def tangent_frames(outward_normals: np.ndarray) -> np.ndarray:
    """Right-handed contact frames (inward normal, downhill, side).

    Parameters
    ----------
    outward_normals : (n, 3) float64
        Unit outward surface normals.

    Returns
    -------
    frames : (n, 3, 3) float64
        ``frames[v, :, 0]`` is the inward normal ``n``, ``[:, :, 1]`` is
        ``t1`` (downhill), ``[:, :, 2]`` is ``t2 = n x t1``. Columns are
        orthonormal: ``frames[v] @ rbar`` maps tangent to world coordinates.
    """
    inward = -np.asarray(outward_normals, dtype=np.float64)
    down = np.array([0.0, -1.0, 0.0])
    # downhill: world down minus its normal part
    t1 = down[None, :] - (inward @ down)[:, None] * inward
    length = np.linalg.norm(t1, axis=1)
    flat = length < 1e-8
    if flat.any():
        # horizontal tangent plane: use +Z, or +X where +Z is (nearly) normal
        alt = np.where(
            np.abs(inward[flat, 2:3]) < 0.9, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]])
        )
        alt = alt - np.einsum("ij,ij->i", alt, inward[flat])[:, None] * inward[flat]
        t1[flat] = alt
        length[flat] = np.linalg.norm(alt, axis=1)
    t1 /= np.where(length > 0, length, 1.0)[:, None]
    t2 = np.cross(inward, t1)
    return np.stack([inward, t1, t2], axis=2)


def local_reaction_weights(
    frames: np.ndarray, mu: float, *, cap: float = DEFAULT_WEIGHT_CAP
) -> np.ndarray:
    """The paper's local reaction weights (Eqs. 2-3), capped.

    Parameters
    ----------
    frames : (n, 3, 3) float64
        Contact frames from :func:`tangent_frames`.
    mu : float
        Friction coefficient (>= 0).
    cap : float
        Largest weight, see the module docstring.

    Returns
    -------
    weights : (n, 3) float64
        ``(w_n, w_t1, w_t2)`` per vertex, each in ``[1, cap]``.
    """
    f = np.array([0.0, -1.0, 0.0])
    # components of the unit load in the frame (f_t2 = 0 by construction)
    # the support answers f with r_n = -f_n along the inward normal; it can
    # only push, so only the part of f pressing into it (f . n_in < 0) counts
    f_n = np.maximum(-(frames[:, :, 0] @ f), 0.0)
    f_t1 = np.abs(frames[:, :, 1] @ f)
    f_t2 = np.abs(frames[:, :, 2] @ f)
    r_n = f_n
    r_t1 = np.minimum(f_t1, mu * f_n)
    r_t2 = np.minimum(f_t2, mu * f_n)
    floor = 1.0 / cap
    w_n = 1.0 / np.maximum(np.sqrt(r_n**2 + r_t1**2 + r_t2**2), floor)
    w_t1 = 1.0 / np.maximum(np.sqrt(r_n**2 + r_t1**2), floor)
    w_t2 = 1.0 / np.maximum(np.sqrt(r_n**2 + r_t2**2), floor)
    return np.stack([w_n, w_t1, w_t2], axis=1)
