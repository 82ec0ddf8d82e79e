"""Residuals of a pressure solution and its data file (npz; the PLY and PNG: seatkit.export.pressure).

``pressure.npz`` keys (all SI):

=================  ===========  ===================================================
key                shape/dtype  meaning
=================  ===========  ===================================================
vertices           (n, 3) f8    posed body vertices, m
faces              (m, 3) i8    triangles
force              (n, 3) f8    world reaction force on each vertex, N
normal_force       (n,) f8      force component along the inward normal, N (>= 0)
pressure           (n,) f8      normal_force / area, Pa
shear              (n,) f8      tangential force / area, Pa
area               (n,) f8      mixed Voronoi area, m^2
contact            (n,) bool    vertices allowed to carry a reaction
segment_mass       (21,) f8     kg
segment_com        (21, 3) f8   posed centres of mass, m
joint_force        (20, 3) f8   force parent -> child at each joint, N
joint_moment       (20, 3) f8   moment parent -> child at each joint, N m
joint_position     (20, 3) f8   posed joint positions, m
solve_seconds      () f8        wall time of the solve, s
lam, mu            () f8        parameters used (lam = inf: rigid body)
status             () str       solver status
residual_names     (r,) str     names of the recomputed residuals
residual_values    (r,) f8      their values (see ``equilibrium_residuals``)
=================  ===========  ===================================================
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from seatkit.constants import GRAVITY
from seatkit.skeleton import N_SEGMENTS, PARENTS

__all__ = ["equilibrium_residuals", "write_npz", "NPZ_KEYS"]

NPZ_KEYS = (
    "vertices",
    "faces",
    "force",
    "normal_force",
    "pressure",
    "shear",
    "area",
    "contact",
    "segment_mass",
    "segment_com",
    "joint_force",
    "joint_moment",
    "joint_position",
    "solve_seconds",
    "lam",
    "mu",
    "status",
    "residual_names",
    "residual_values",
)


def equilibrium_residuals(
    body,
    *,
    force: np.ndarray,
    joint_force: np.ndarray,
    joint_moment: np.ndarray,
    frames: np.ndarray,
    index: np.ndarray,
    contact: np.ndarray,
    mu: float,
) -> dict:
    """Recompute every constraint of the paper's QP from a solution.

    Uses the segment-by-segment balance of Eqs. (5)-(6) with the joint loads
    as given (parent receives ``-F_j``, ``-M_j``: action = reaction), not the
    reduced system the solver used, so it checks the solver independently.

    Parameters
    ----------
    body : Body
    force : (n, 3) float64
        World reaction per vertex, N.
    joint_force, joint_moment : (20, 3) float64
    frames : (k, 3, 3) float64
        Contact frames of the contact vertices ``index``.
    index : (k,) int64
    contact : (n,) bool
    mu : float

    Returns
    -------
    residuals : dict of str to float
        ``segment_force`` (N) and ``segment_moment`` (N m): largest balance
        error of any segment; ``total_force_relative``: |sum of reactions +
        weight| / weight; ``net_moment`` (N m): moment of gravity and
        reactions about the origin; ``min_normal_force`` (N);
        ``friction_excess`` (N): largest ``|t_i| - mu n``;
        ``force_outside_contact`` (N): largest reaction off the contact set.
    """
    gravity = np.zeros((N_SEGMENTS, 3))
    gravity[:, 1] = -GRAVITY * body.segment_mass
    weight = float(-gravity[:, 1].sum())
    com = body.segment_com
    alpha = body.weights
    seg_f = alpha.T @ force + gravity
    seg_m = alpha.T @ np.cross(body.vertices, force) - np.cross(com, alpha.T @ force)
    child = np.arange(1, N_SEGMENTS)
    parent = PARENTS[child]
    J = body.joints[child]
    # child receives (F, M) at the joint, parent (-F, -M)
    np.add.at(seg_f, child, joint_force)
    np.add.at(seg_f, parent, -joint_force)
    np.add.at(seg_m, child, np.cross(J - com[child], joint_force) + joint_moment)
    np.add.at(seg_m, parent, -np.cross(J - com[parent], joint_force) - joint_moment)
    total = force.sum(axis=0) + gravity.sum(axis=0)
    net_moment = np.cross(body.vertices, force).sum(axis=0) + np.cross(com, gravity).sum(axis=0)
    rbar = np.einsum("kdi,kd->ki", frames, force[index]) if len(index) else np.zeros((0, 3))
    n = rbar[:, 0]
    excess = np.abs(rbar[:, 1:]) - mu * n[:, None] if len(index) else np.zeros((0, 2))
    off = force[~contact]
    return {
        "segment_force": float(np.abs(seg_f).max()),
        "segment_moment": float(np.abs(seg_m).max()),
        "total_force_relative": float(np.linalg.norm(total) / weight),
        "net_moment": float(np.linalg.norm(net_moment)),
        "min_normal_force": float(n.min()) if len(n) else 0.0,
        "friction_excess": float(excess.max()) if excess.size else 0.0,
        "force_outside_contact": float(np.abs(off).max()) if off.size else 0.0,
    }


def write_npz(path, body, field) -> Path:
    """Write a body and its pressure field to ``path`` (keys: module docstring).

    Written atomically (:func:`seatkit.io.atomic_write`).
    """
    from seatkit.io import atomic_write

    path = Path(path)
    names = sorted(field.residuals)
    arrays = {
        "vertices": body.vertices,
        "faces": np.asarray(body.faces, dtype=np.int64),
        "force": field.force,
        "normal_force": field.normal_force,
        "pressure": field.pressure,
        "shear": field.shear,
        "area": field.area,
        "contact": field.contact,
        "segment_mass": body.segment_mass,
        "segment_com": body.segment_com,
        "joint_force": field.joint_force,
        "joint_moment": field.joint_moment,
        "joint_position": body.joints[1:],
        "solve_seconds": np.float64(field.solve_seconds),
        "lam": np.float64(field.params.get("lambda", np.nan)),
        "mu": np.float64(field.params.get("mu", np.nan)),
        "status": np.str_(field.status),
        "residual_names": np.array(names, dtype=str),
        "residual_values": np.array([field.residuals[k] for k in names], dtype=np.float64),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    return path
