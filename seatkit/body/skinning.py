"""Forward kinematics and linear blend skinning of the 21-segment skeleton.

Pose convention (see :class:`seatkit.model.Pose`): ``rotations[s]`` is the
rotation vector of segment ``s`` relative to its parent, expressed in the
world axes of the rest pose (every rest frame is aligned with the world),
applied about the segment's proximal joint. Forward kinematics::

    G_0 = R_0                       p_0 = joint_0 + translation
    G_s = G_parent(s) @ R_s         p_s = p_parent + G_parent @ (joint_s - joint_parent)

and a point ``x`` rigidly attached to segment ``s`` moves to
``G_s @ (x - joint_s) + p_s``. Linear blend skinning (Magnenat-Thalmann et
al. 1988, the paper's Section 4.1) blends these 21 affine maps with the
vertex weights: ``v = sum_s w_s (G_s @ (v0 - joint_s) + p_s)``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial.transform import Rotation

from seatkit.cache import IdentityCache
from seatkit.model import Body, Pose, RiggedBody
from seatkit.skeleton import N_SEGMENTS, PARENTS

__all__ = ["forward_kinematics", "segment_transforms", "skin_vertices", "pose_rig"]


def forward_kinematics(rest_joints: np.ndarray, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    """Global rotation and posed proximal joint of every segment.

    Parameters
    ----------
    rest_joints : (21, 3) float64
        Rest position of each segment's proximal joint, m.
    pose : Pose

    Returns
    -------
    rotations : (21, 3, 3) float64
        Global rotation ``G_s`` of each segment.
    joints : (21, 3) float64
        Posed proximal joint ``p_s`` of each segment, m.
    """
    local = Rotation.from_rotvec(pose.rotations).as_matrix()  # (21, 3, 3) R_s
    rest_joints = np.asarray(rest_joints, dtype=np.float64)
    # rest offset of each joint from its parent's joint (root: unused)
    offsets = rest_joints - rest_joints[np.maximum(PARENTS, 0)]
    glob = np.empty((N_SEGMENTS, 3, 3))
    joints = np.empty((N_SEGMENTS, 3))
    glob[0] = local[0]
    joints[0] = rest_joints[0] + pose.translation
    # PARENTS[s] < s for every s: one pass in index order is a topological order
    for s in range(1, N_SEGMENTS):
        parent = PARENTS[s]
        glob[s] = glob[parent] @ local[s]
        joints[s] = joints[parent] + glob[parent] @ offsets[s]
    return glob, joints


def segment_transforms(rest_joints: np.ndarray, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    """The affine map of each segment, rest position to posed position.

    Parameters
    ----------
    rest_joints : (21, 3) float64
    pose : Pose

    Returns
    -------
    linear : (21, 3, 3) float64
        ``G_s``.
    offset : (21, 3) float64
        ``p_s - G_s @ joint_s``, so that ``x -> linear[s] @ x + offset[s]``.
    """
    glob, joints = forward_kinematics(rest_joints, pose)
    offset = joints - np.einsum("sij,sj->si", glob, rest_joints)
    return glob, offset


#: Sparse copies of weight matrices, keyed by id of the dense array (each
#: vertex touches 1-7 of the 21 segments; a CSR product is single-threaded
#: and steady, where a dense BLAS product stalls on a loaded machine).
_SPARSE_WEIGHTS = IdentityCache()


def _sparse_weights(weights: np.ndarray) -> sp.csr_matrix:
    # an array that cannot be weakly referenced is not cached
    return _SPARSE_WEIGHTS.get((weights,), lambda: sp.csr_matrix(weights))


def skin_vertices(vertices: np.ndarray, weights: np.ndarray, linear: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Linear blend skinning.

    Parameters
    ----------
    vertices : (n, 3) float64
        Rest positions.
    weights : (n, 21) float64
        Skinning weights, rows summing to 1.
    linear : (21, 3, 3) float64
    offset : (21, 3) float64

    Returns
    -------
    posed : (n, 3) float64
    """
    # blended 3x3 matrix and offset per vertex, (n, 12): 9 matrix entries, 3 offset
    blended = _sparse_weights(weights) @ np.concatenate([linear.reshape(N_SEGMENTS, 9), offset], axis=1)
    blended_linear = blended[:, :9].reshape(-1, 3, 3)
    return np.einsum("nij,nj->ni", blended_linear, vertices) + blended[:, 9:]


def pose_rig(rig: RiggedBody, pose: Pose, *, ground: bool = True) -> Body:
    """Pose a rigged body by linear blend skinning.

    Parameters
    ----------
    rig : RiggedBody
    pose : Pose
    ground : bool
        Move the posed body vertically so that its lowest vertex is at y = 0.

    Returns
    -------
    Body
        Posed vertices, joints, tips and segment centres of mass; segment
        masses and region labels copied from ``rig``.
    """
    linear, offset = segment_transforms(rig.joints, pose)
    vertices = skin_vertices(rig.vertices, rig.weights, linear, offset)
    joints = np.einsum("sij,sj->si", linear, rig.joints) + offset
    tips = np.einsum("sij,sj->si", linear, rig.tips) + offset
    if ground:
        lift = np.array([0.0, -vertices[:, 1].min(), 0.0])
        vertices = vertices + lift
        joints = joints + lift
        tips = tips + lift
    segment_com = joints + rig.com_ratio[:, None] * (tips - joints)
    name = f"{rig.name}:{pose.name}" if pose.name else rig.name
    return Body(
        vertices=vertices,
        faces=rig.faces,
        weights=rig.weights,
        joints=joints,
        tips=tips,
        segment_mass=rig.segment_mass,
        segment_com=segment_com,
        name=name,
        region_labels=rig.region_labels,
    )
