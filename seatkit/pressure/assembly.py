"""Assembly of the paper's equilibrium QP (Section 4, Appendix A), reduced.

The paper's unknowns are a force and a moment per segment-joint incidence
and a reaction per contact vertex; its equalities are the force and moment
balance of each of the 21 segments (about its centre of mass, reactions
shared by skinning weights) and action = reaction at each of the 20 joints.

We build action = reaction in (one force ``F_j`` and one moment ``M_j`` per
joint: what the parent exerts on the child, the parent receiving ``-F_j``,
``-M_j``) and then eliminate the joint forces along the kinematic tree:

- The balance of the *subtree* hanging below joint ``j`` (the child segment
  ``j + 1`` and all its descendants) involves only ``F_j``, ``M_j`` and the
  external loads on that subtree, because every internal joint force cancels
  in pairs. Its force balance gives ``F_j`` and its moment balance about the
  joint position ``J_j`` gives ``M_j`` as affine functions of the reactions.
- The subtree of the root is the whole body: its 6 balance equations contain
  no joint unknown. They are the only equalities left on the reactions.

The map from joint unknowns to segment balance residuals is triangular along
the tree, so this is an exact change of variables, not an approximation:
each reaction field satisfying whole-body balance has exactly one set of
joint forces and moments satisfying the paper's 126 + 120 equations.

What remains is a QP in the reactions ``rbar`` (3 per contact vertex, tangent
frame) and the 60 joint-moment components ``M``::

    minimise   c_M sum_j |M_j|^2 + sum_v sum_i D_vi rbar_vi^2
    subject to M_j + K_j rbar = e_j            (60 rows, one per moment component)
               B rbar = e_B                    (6 rows, whole-body balance)
               rbar_v in the friction pyramid  (per vertex)

with ``D_v = lambda w_v^2 / A_v``. The 66 rows are applied through the
skinning weights and a per-segment row map, never as a dense matrix (see
:class:`ReducedProblem`). For ``lambda = inf`` (rigid body) the moments are
not minimised: the 60 moment rows are dropped and only the 6 whole-body rows
remain, with ``D_v = w_v^2 / A_v``.

``c_M = 2`` (:data:`MOMENT_INCIDENCES`): the paper's moment sum runs over
segment-joint incidences (two per joint, equal and opposite), so each joint
moment is counted twice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from seatkit.cache import IdentityCache
from seatkit.constants import GRAVITY
from seatkit.geometry.normals import kept_vertex_normals
from seatkit.pressure.areas import mixed_voronoi_areas
from seatkit.pressure.weights import DEFAULT_WEIGHT_CAP, local_reaction_weights, tangent_frames
from seatkit.skeleton import N_JOINTS, N_SEGMENTS, PARENTS

__all__ = [
    "MOMENT_INCIDENCES",
    "ReducedProblem",
    "subtree_matrix",
    "body_geometry",
    "assemble",
    "joint_loads",
    "segment_gravity",
]

#: Number of times each joint moment enters the paper's objective (Eq. 4):
#: one per segment-joint incidence.
MOMENT_INCIDENCES = 2.0


def subtree_matrix() -> np.ndarray:
    """Which segments hang below which joint.

    Returns
    -------
    S : (21, 20) float64
        ``S[s, j] = 1`` when segment ``s`` is the child of joint ``j``
        (segment ``j + 1``) or one of its descendants.
    """
    S = np.zeros((N_SEGMENTS, N_JOINTS))
    for j in range(N_JOINTS):
        S[j + 1, j] = 1.0
    # propagate membership up the tree: parents are listed before children,
    # so walking segments backwards visits every child before its parent
    for s in range(N_SEGMENTS - 1, 0, -1):
        p = PARENTS[s]
        if p > 0:
            S[:, p - 1] = np.maximum(S[:, p - 1], S[:, s - 1])
    return S


@dataclass(frozen=True)
class BodyGeometry:
    """Per-vertex geometry of a body surface.

    Attributes
    ----------
    area : (n,) float64
        Mixed Voronoi areas, m^2.
    normal : (n,) float64
        Outward unit normals.
    """

    area: np.ndarray
    normal: np.ndarray


#: :func:`body_geometry`'s areas by the vertex and face arrays (their identity): a build solves
#: the importance map and then each design's contact pressure on the same body.
_AREAS = IdentityCache(maxsize=8)


def body_geometry(vertices: np.ndarray, faces: np.ndarray) -> BodyGeometry:
    """Mixed Voronoi areas and outward normals of a body surface.

    Faces must be counter-clockwise seen from outside (the :class:`Body`
    contract); the normals then point out of the body. Computed once for
    the last few vertex and face arrays in this process; each call gets its
    own copy of the arrays.
    """
    area = _AREAS.get((vertices, faces), lambda: mixed_voronoi_areas(vertices, faces))
    return BodyGeometry(area=area.copy(), normal=kept_vertex_normals(vertices, faces).copy())


@dataclass(frozen=True)
class ReducedProblem:
    """The reduced QP of one body and contact set (see the module docstring).

    The constraint columns are never stored densely. A reaction ``rbar_v``
    (tangent frame) acts on the rows through the 6-vector ``(f_v, x_v x f_v)``
    (world force and its moment about the origin) and the vertex's skinning
    weights: the columns of vertex ``v`` are ``sum_s alpha_vs K_s L_v`` with
    ``L_v = [T_v; [x_v]_x T_v]`` (6 x 3) and ``K_s`` (r x 6) the rows felt by
    a load on segment ``s`` (the joints above it and the whole body). Every
    product the solver needs then costs O(k) small operations.

    Attributes
    ----------
    index : (k,) int64
        Body vertex of each contact unknown.
    frames : (k, 3, 3) float64
        Tangent frames (columns n, t1, t2).
    points : (k, 3) float64
        Contact vertex positions, m.
    D : (k, 3) float64
        Objective diagonal per tangent component.
    alpha : (k, 21) scipy.sparse.csr_matrix
        Skinning weights of the contact vertices (rows sum to 1).
    pairs : (441, k) scipy.sparse.csr_matrix
        ``pairs[21 s + t, v] = alpha_vs alpha_vt``.
    K : (21, r, 6) float64
        Row map of a load on each segment; r = 66 (6 when rigid).
    e : (r,) float64
        Right-hand side: rows ``3j..3j+2`` minus the moment of gravity on the
        subtree of joint ``j`` about the joint, rows ``r-6..r-4`` the body
        weight (upwards), the last three minus the moment of gravity about
        the body's centre of mass (zero).
    rigid : bool
        ``lambda = inf``: no moment rows.
    moment_weight : float
        ``c_M`` (0 when rigid).
    weights : (k, 3) float64
        Local reaction weights (Eqs. 2-3).
    reference : (3,) float64
        Point the whole-body moment rows are taken about (the centre of mass).
    """

    index: np.ndarray
    frames: np.ndarray
    points: np.ndarray
    D: np.ndarray
    alpha: sp.csr_matrix
    pairs: sp.csr_matrix
    K: np.ndarray
    e: np.ndarray
    rigid: bool
    moment_weight: float
    weights: np.ndarray
    reference: np.ndarray

    @property
    def n_moment_rows(self) -> int:
        """Number of joint-moment rows (60, or 0 when rigid)."""
        return 0 if self.rigid else 3 * N_JOINTS

    @property
    def n_rows(self) -> int:
        """Number of equality rows r (66, or 6 when rigid)."""
        return self.K.shape[1]

    def apply_transpose(self, y: np.ndarray) -> np.ndarray:
        """``E^T y`` per vertex in tangent coordinates, (k, 3)."""
        u = np.einsum("sra,r->sa", self.K, y)  # (21, 6) per-segment dual load
        uv = self.alpha @ u  # (k, 6)
        world = uv[:, :3] + np.cross(uv[:, 3:], self.points)  # [x]_x^T m = m x x
        return np.einsum("kdi,kd->ki", self.frames, world)

    def apply(self, rbar: np.ndarray) -> np.ndarray:
        """``E rbar`` (reaction part of the rows), (r,)."""
        f = np.einsum("kdi,ki->kd", self.frames, rbar)
        w = np.concatenate([f, np.cross(self.points, f)], axis=1)  # (k, 6)
        per_segment = self.alpha.T @ w  # (21, 6)
        return np.einsum("sra,sa->r", self.K, per_segment)

    def normal_matrix(self, U: np.ndarray) -> np.ndarray:
        """``sum_v E_v U_v U_v^T E_v^T`` for per-vertex factors ``U`` (k, 3, c)."""
        TU = np.matmul(self.frames, U)  # (k, 3, c) world directions
        LU = np.concatenate([TU, np.cross(self.points[:, :, None], TU, axis=1)], axis=1)  # (k, 6, c)
        Q = np.matmul(LU, np.swapaxes(LU, 1, 2)).reshape(len(U), 36)
        P = np.asarray(self.pairs @ Q).reshape(N_SEGMENTS, N_SEGMENTS, 6, 6)
        Pbig = P.transpose(0, 2, 1, 3).reshape(6 * N_SEGMENTS, 6 * N_SEGMENTS)
        Kbig = self.K.transpose(1, 0, 2).reshape(self.n_rows, 6 * N_SEGMENTS)
        # tiny products through einsum, not BLAS: multithreaded BLAS on a
        # 66 x 126 matrix costs 0.1 ms on an idle machine but up to 100 ms
        # when the cores are busy (thread hand-off), einsum a steady 1 ms
        KP = np.einsum("ab,bc->ac", Kbig, Pbig)
        return np.einsum("ac,dc->ad", KP, Kbig)


def segment_gravity(segment_mass: np.ndarray) -> np.ndarray:
    """(21, 3) float64 weight of each segment, N (along -Y)."""
    g = np.zeros((len(segment_mass), 3))
    g[:, 1] = -GRAVITY * segment_mass
    return g


def _skew(a: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrices of (..., 3) vectors."""
    m = np.zeros(a.shape[:-1] + (3, 3))
    m[..., 0, 1], m[..., 0, 2] = -a[..., 2], a[..., 1]
    m[..., 1, 0], m[..., 1, 2] = a[..., 2], -a[..., 0]
    m[..., 2, 0], m[..., 2, 1] = -a[..., 1], a[..., 0]
    return m


def _pair_matrix(alpha: sp.csr_matrix) -> sp.csr_matrix:
    """(441, k) products of each vertex's pairs of skinning weights."""
    coo = alpha.tocoo()
    order = np.lexsort((coo.col, coo.row))
    rows, cols, vals = coo.row[order], coo.col[order], coo.data[order]
    k = alpha.shape[0]
    counts = np.bincount(rows, minlength=k)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    rep = counts[rows]  # each entry pairs with every entry of its row
    e1 = np.repeat(np.arange(len(rows)), rep)
    offset = np.arange(len(e1)) - np.repeat(np.cumsum(rep) - rep, rep)
    e2 = np.repeat(start[rows], rep) + offset
    return sp.csr_matrix(
        (vals[e1] * vals[e2], (cols[e1] * N_SEGMENTS + cols[e2], rows[e1])),
        shape=(N_SEGMENTS * N_SEGMENTS, k),
    )


def assemble(
    body,
    *,
    contact: np.ndarray,
    lam: float,
    mu: float,
    geometry: BodyGeometry,
    weight_cap: float = DEFAULT_WEIGHT_CAP,
) -> ReducedProblem:
    """Build the reduced problem.

    Parameters
    ----------
    body : Body
        Skinning weights with rows summing to 1.
    contact : (n,) bool
        Vertices that may carry a reaction (already intersected with the
        user weights and with ``area > 0``).
    lam : float
        The paper's lambda; ``inf`` for a rigid body.
    mu : float
        Friction coefficient (used by the local weights).
    geometry : BodyGeometry
    weight_cap : float
        Cap of the local reaction weights.

    Returns
    -------
    ReducedProblem
    """
    index = np.flatnonzero(contact)
    x = body.vertices[index]
    frames = tangent_frames(geometry.normal[index])
    w = local_reaction_weights(frames, mu, cap=weight_cap)
    area = geometry.area[index]
    rigid = bool(np.isinf(lam))
    D = (1.0 if rigid else float(lam)) * w**2 / area[:, None]
    alpha = sp.csr_matrix(body.weights[index])
    alpha.eliminate_zeros()

    gravity = segment_gravity(body.segment_mass)
    com = (body.segment_mass @ body.segment_com) / float(body.segment_mass.sum())
    # whole-body rows: force, and moment about the centre of mass: m - c x f
    eye = np.eye(3)
    whole = np.zeros((6, 6))
    whole[:3, :3] = eye
    whole[3:, :3] = -_skew(com)
    whole[3:, 3:] = eye
    e_force = -gravity.sum(axis=0)
    e_moment = -np.cross(body.segment_com - com, gravity).sum(axis=0)
    if rigid:
        K = np.broadcast_to(whole, (N_SEGMENTS, 6, 6)).copy()
        e = np.concatenate([e_force, e_moment])
        return ReducedProblem(index, frames, x, D, alpha, _pair_matrix(alpha), K, e, True, 0.0, w, com)

    S = subtree_matrix()
    J = body.joints[1:]  # (20, 3) joint positions
    # a load (f, m about the origin) on segment s below joint j has moment
    # m - J_j x f about the joint
    joint_block = np.concatenate([-_skew(J), np.broadcast_to(eye, (N_JOINTS, 3, 3))], axis=2)  # (20, 3, 6)
    K = np.zeros((N_SEGMENTS, 3 * N_JOINTS + 6, 6))
    K[:, : 3 * N_JOINTS] = (S[:, :, None, None] * joint_block[None]).reshape(N_SEGMENTS, 3 * N_JOINTS, 6)
    K[:, 3 * N_JOINTS :] = whole
    # subtree gravity moment about each joint: e_j = -sum_s S_sj (com_s - J_j) x g_s
    arms = body.segment_com[:, None, :] - J[None, :, :]  # (21, 20, 3)
    e_joint = -np.einsum("sj,sjd->jd", S, np.cross(arms, gravity[:, None, :]))
    e = np.concatenate([e_joint.ravel(), e_force, e_moment])
    return ReducedProblem(index, frames, x, D, alpha, _pair_matrix(alpha), K, e, False, MOMENT_INCIDENCES, w, com)


def joint_loads(body, force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint forces and moments implied by a reaction field.

    Each joint's force and moment follow from the balance of the subtree
    below it (see the module docstring).

    Parameters
    ----------
    body : Body
    force : (n, 3) float64
        World reaction force per vertex, N.

    Returns
    -------
    joint_force : (20, 3) float64
        Force the parent exerts on the child at each joint, N.
    joint_moment : (20, 3) float64
        Moment the parent exerts on the child at each joint, N m.
    """
    S = subtree_matrix()
    gravity = segment_gravity(body.segment_mass)
    J = body.joints[1:]
    # per-segment sums of skinned reactions and of their moments about the origin
    seg_force = body.weights.T @ force  # (21, 3)
    seg_moment0 = body.weights.T @ np.cross(body.vertices, force)  # (21, 3)
    sub_force = S.T @ (seg_force + gravity)  # (20, 3) external force on each subtree
    sub_moment0 = S.T @ (seg_moment0 + np.cross(body.segment_com, gravity))
    # moment about J_j = moment about origin - J_j x (total force)
    sub_moment = sub_moment0 - np.cross(J, sub_force)
    return -sub_force, -sub_moment
