"""Supporting planes: importance-weighted RANSAC and the paper's plane quality.

A candidate plane is defined by three body vertices drawn with
probabilities proportional to their importance (paper Section 5.2); the
reference normals (the segment's PCA normal, or the template's frame normal
where PCA is meaningless) compete as two more candidates. Every candidate is
moved along its normal until it touches the segment from below (at most
``max_penetration`` into the skin), so RANSAC effectively samples the
*orientation* of a supporting plane. Its quality is the paper's

    w_P = sum_{v in V_P} w(v) (1 - lambda_r + p_r lambda_r) (1 - lambda_d + p_d lambda_d)

where ``V_P`` are the segment's vertices within the support distance of the
plane, ``p_r`` rewards a normal close to the segment's PCA normal (Eq. 5)
and ``p_d`` rewards a row intersection direction close to ``d_side`` (Eq. 6).
Both penalties are 1 for a perfect plane and 0 at or beyond their limits.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from seatkit.cache import LRUCache, value_key
from seatkit.geometry.closest import row_norms

__all__ = [
    "Plane",
    "pca_normal",
    "penalty_reference",
    "penalty_direction",
    "fit_support_plane",
    "intersect_planes",
    "unit",
    "cross",
]

_EPS = 1e-12


def unit(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` (..., 3) scaled to unit length (zero rows stay zero)."""
    v = np.asarray(v)
    # np.linalg.norm(v, axis=-1, keepdims=True) of a real array, to the bit (row_norms)
    n = row_norms(v if v.dtype.kind == "f" else v.astype(np.float64))[..., None]
    return v / np.maximum(n, _EPS)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of vectors (..., 3) broadcast against each other: the same numbers, without its axis handling and copies.

    Each component is one product less another (``a1 b2 - a2 b1``, ...),
    as numpy computes it; the fit calls this a few hundred times on small
    arrays, where ``np.cross``'s own overhead was most of its cost.
    """
    a, b = np.asarray(a), np.asarray(b)
    dtype = np.promote_types(a.dtype, b.dtype)
    a, b = a.astype(dtype, copy=False), b.astype(dtype, copy=False)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.multiply(a1, b2, out=out[..., 0])
    out[..., 0] -= a2 * b1
    np.multiply(a2, b0, out=out[..., 1])
    out[..., 1] -= a0 * b2
    np.multiply(a0, b1, out=out[..., 2])
    out[..., 2] -= a1 * b0
    return out


@dataclass(frozen=True)
class Plane:
    """An oriented plane; ``normal`` points from the plane towards the body.

    Attributes
    ----------
    point : (3,) float64
        A point on the plane, m.
    normal : (3,) float64
        Unit normal.
    quality : float
        The paper's w_P of this plane (0 for planes not found by RANSAC).
    """

    point: np.ndarray
    normal: np.ndarray
    quality: float = 0.0

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """(k,) float64 signed distance of ``points`` (k, 3), positive on the body side."""
        return (points - self.point) @ self.normal

    def project(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) float64 orthogonal projection of ``points`` onto the plane."""
        return points - np.outer(self.signed_distance(points), self.normal)


def pca_normal(points: np.ndarray, *, fallback: np.ndarray | None = None, max_ratio: float = 0.5, max_angle: float = np.pi / 4) -> np.ndarray:
    """(3,) float64 direction of least variance of ``points`` (k, 3).

    With a ``fallback``, the PCA direction is used only when it is
    meaningful for a support: the two smallest variances differ (ratio
    below ``max_ratio``; a limb is a cylinder, any direction across it is
    as flat) and it lies within ``max_angle`` of the fallback (a thin
    horizontal slice of the torso is flattest vertically, but its backrest
    faces forwards). Otherwise ``fallback`` is returned.
    """
    centred = points - points.mean(0)
    vals, vecs = np.linalg.eigh(centred.T @ centred)
    if fallback is not None:
        ref = unit(np.asarray(fallback, dtype=np.float64))
        if vals[0] > max_ratio * vals[1] or abs(vecs[:, 0] @ ref) < np.cos(max_angle):
            return ref
    return vecs[:, 0]


def _fold_angle(cos: np.ndarray) -> np.ndarray:
    """Angle between two undirected lines from the |cosine| of their directions, rad."""
    return np.arccos(np.clip(np.abs(cos), 0.0, 1.0))


def penalty_reference(normals: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The paper's p^r (Eq. 5) of candidate ``normals`` (k, 3).

    ``reference`` (3,) is the segment's PCA normal, whose sign is arbitrary,
    so the angle is taken between undirected lines (0 to pi/2).

    Returns
    -------
    (k,) float64
        1 - min(4/pi * angle, 1): 1 for a normal along the reference, 0 at 45 deg or more.
    """
    sine = np.linalg.norm(cross(normals, reference), axis=-1)
    dot = np.abs(normals @ reference)
    angle = np.abs(np.arctan2(sine, dot))
    return 1.0 - np.minimum(4.0 / np.pi * angle, 1.0)


def penalty_direction(d_side: np.ndarray, d_ir: np.ndarray, m_alpha: float) -> np.ndarray:
    """The paper's p^d (Eq. 6): 1 - min(angle(d_side, d_ir), m_alpha) / m_alpha.

    Parameters
    ----------
    d_side, d_ir : (k, 3) float64
        Side direction of each candidate and direction of its line of
        intersection with the previous row's plane (undirected).
    m_alpha : float
        Largest penalised deviation, rad.
    """
    cos = np.einsum("ij,ij->i", unit(d_side), unit(d_ir))
    return 1.0 - np.minimum(_fold_angle(cos), m_alpha) / m_alpha


@dataclass(frozen=True)
class PlaneFitResult:
    """A fitted plane and what RANSAC saw.

    Attributes
    ----------
    plane : Plane
    candidates : int
        Candidates drawn.
    rejected : dict of str to int
        Candidates discarded, by reason.
    supported : (k,) bool
        Which of the segment's vertices lie within the support distance.
    """

    plane: Plane
    candidates: int
    rejected: dict
    supported: np.ndarray


#: :func:`fit_support_plane`'s answers by their inputs: the template's starts
#: of one random stream run the steps before the first optional step they
#: drop alike (docs/templates.md, "The starts"), each asking for the same
#: planes from the same stream state.
_FITS = LRUCache(1024)


def _remembered(fit):
    """``fit`` (a function of arrays, numbers and a random stream ``rng``, given by keyword) answered once per inputs and stream state.

    The key is a digest of every argument's bytes (arrays with their type
    and shape), as given (an argument left to its default and the same value
    given are two keys), and of the stream's state; a repeated call gets a
    copy of the first answer, and the stream is left in the state the first
    call left it in, so the caller sees exactly what running ``fit`` again
    would give it.
    """

    @functools.wraps(fit)
    def remembered(*args, rng, **kwargs):
        key = value_key(rng.bit_generator.state, args, kwargs)
        hit = _FITS.peek(key)
        if hit is None:
            result = fit(*args, rng=rng, **kwargs)
            _FITS.get(key, lambda: (_copy_fit(result), rng.bit_generator.state))
            return result
        result, after = hit
        rng.bit_generator.state = after
        return _copy_fit(result)

    return remembered


def _copy_fit(result: "PlaneFitResult") -> "PlaneFitResult":
    """A copy of ``result`` that shares no mutable part with it."""
    plane = result.plane
    return PlaneFitResult(Plane(plane.point.copy(), plane.normal.copy(), plane.quality), result.candidates, dict(result.rejected), result.supported.copy())


@_remembered
def fit_support_plane(
    points: np.ndarray,
    importance: np.ndarray,
    *,
    rng: np.random.Generator,
    iterations: int,
    support_distance: float,
    max_penetration: float,
    body_side: np.ndarray,
    bone: np.ndarray,
    lambda_r: float,
    lambda_d: float = 0.0,
    m_alpha: float = np.pi / 6,
    previous_normal: np.ndarray | None = None,
    max_row_angle: float = np.pi / 2,
    neighbours: np.ndarray | None = None,
    max_neighbour_cut: float = 1.0,
    fixed: np.ndarray | None = None,
    candidates: np.ndarray | None = None,
    side_hint: np.ndarray | None = None,
    max_side_angle: float = np.pi / 3,
    fallback_normal: np.ndarray | None = None,
    importance_floor: float = 1e-3,
    reference: np.ndarray | None = None,
    cone: tuple | None = None,
) -> PlaneFitResult:
    """Importance-weighted RANSAC for the plane that best supports a segment.

    Parameters
    ----------
    points : (k, 3) float64
        Vertices of the segment(s) the face supports, m.
    importance : (k,) float64
        Their importance w(v) (pressure scaled to [0, 1]).
    rng : numpy.random.Generator
        Source of every random choice.
    iterations : int
        Candidate planes drawn.
    support_distance : float
        A vertex within this distance of the plane is supported, m.
    max_penetration : float
        How far a candidate may sink into the segment's skin, m.
    body_side : (3,) float64
        A point on the body side of the plane (the segment's centroid); it
        orients every normal.
    bone : (3,) float64
        Bone direction d^body of the segment (any sign).
    lambda_r, lambda_d : float
        Weights of the penalties p^r and p^d.
    m_alpha : float
        Deviation of d^ir from d^side at which p^d reaches 0, rad.
    previous_normal : (3,) float64, optional
        Normal of the previous row's plane; enables p^d and the
        degenerate-face rejection (``max_row_angle``).
    max_row_angle : float
        Candidates whose row line deviates from d^side by more than this
        (rad) would degenerate a face and are rejected.
    neighbours : (q, 3) float64, optional
        Vertices of the adjacent segments; a candidate that cuts them below
        its supported patch (more than ``max_neighbour_cut`` of them deeper
        than ``max_penetration``) is discarded.
    max_neighbour_cut : float
        Fraction of neighbour vertices a candidate may cut.
    fixed : (2, 3) float64, optional
        Two points every candidate must contain (the outer-column step: the
        shared inner vertices). Then each candidate is the plane through them
        and one of ``candidates`` (default: every segment vertex), and the
        plane is not moved along its normal; when every candidate sinks
        deeper than ``max_penetration`` the least sinking one is kept.
    candidates : (c, 3) float64, optional
        Third points tried with ``fixed``.
    side_hint : (3,) float64, optional
        The grid's column direction (the body's right to left). With
        ``bone`` oriented along the grid's rows, a candidate whose
        ``d_side = d_up x n`` points against it would support the segment
        from the wrong side (e.g. in front of the shins) and fold the grid:
        candidates whose d_side deviates from it by more than
        ``max_side_angle`` (rad) are rejected.
    max_side_angle : float
        See ``side_hint``.
    fallback_normal : (3,) float64, optional
        With ``fixed``: when every candidate is rejected, the plane through
        the fixed points closest to this normal (the inner face's).
    importance_floor : float
        Added to the importance for sampling and scoring, so that a segment
        without load still gets a plane.
    reference : (3,) float64, optional
        Reference normal for p^r when the segment's PCA normal is ambiguous
        (see :func:`pca_normal`): the normal of a face whose d_side is the
        body's lateral axis.
    cone : (axis, angle), optional
        Candidates whose normal deviates from ``axis`` (3,) by more than
        ``angle`` (rad) are rejected (an armrest must be nearly horizontal).

    Returns
    -------
    PlaneFitResult
    """
    k = len(points)
    w = importance + importance_floor
    n_ref = pca_normal(points, fallback=reference)
    if fixed is None:
        prob = w / w.sum()
        idx = rng.choice(k, size=(iterations, 3), p=prob)
        a, b, c = points[idx[:, 0]], points[idx[:, 1]], points[idx[:, 2]]
        normals = cross(b - a, c - a)
        anchors = a
        # the reference orientations compete too (a cylinder-like limb with
        # no load gives RANSAC nothing to prefer one tangent plane by)
        refs = [r for r in (reference, n_ref) if r is not None]
        if refs:
            normals = np.vstack([normals, np.asarray(refs, dtype=np.float64)])
            anchors = np.vstack([anchors, np.repeat(points.mean(0)[None] - 1.0 * np.asarray(refs), 1, axis=0)])
    else:
        a, b = fixed
        third = points if candidates is None else candidates
        normals = cross(b - a, third - a)
        anchors = np.broadcast_to(a, third.shape)
    norm = np.linalg.norm(normals, axis=1)
    ok = norm > 1e-9
    normals = normals / np.maximum(norm, 1e-12)[:, None]
    # orient every normal towards the body
    flip = ((body_side - anchors) * normals).sum(1) < 0
    normals[flip] *= -1
    # signed distances of all segment vertices to every candidate, (c, k)
    dist = points @ normals.T - (anchors * normals).sum(1)
    dist = dist.T
    if fixed is None:
        # move each candidate to touch the skin: deepest vertex at -max_penetration
        shift = dist.min(1) + max_penetration
        dist = dist - shift[:, None]
        offsets = (anchors * normals).sum(1) + shift
    else:
        offsets = (anchors * normals).sum(1)
        sinks = dist.min(1) < -max_penetration
        if (ok & ~sinks).any():
            ok &= ~sinks
        else:
            # every candidate sinks: keep the least sinking, nothing else
            least = np.where(ok, dist.min(1), -np.inf)
            ok &= least >= least.max()
    rejected = {"degenerate": int((~ok).sum())}
    supported = np.abs(dist) <= support_distance
    # penalties
    p_r = penalty_reference(normals, n_ref)
    d_up = unit(bone - normals * (normals @ bone)[:, None])
    d_side = cross(d_up, normals)
    if side_hint is not None:
        wrong = d_side @ unit(side_hint) < np.cos(max_side_angle)
        rejected["wrong_side"] = int((wrong & ok).sum())
        ok &= ~wrong
    if cone is not None:
        axis, angle = cone
        off = normals @ unit(np.asarray(axis, dtype=np.float64)) < np.cos(angle)
        rejected["outside_cone"] = int((off & ok).sum())
        ok &= ~off
    p_d = np.ones(len(normals))
    if previous_normal is not None:
        d_ir = cross(normals, previous_normal)
        meets = np.linalg.norm(d_ir, axis=1) > np.sin(np.radians(5.0))
        p_d = np.where(meets, penalty_direction(d_side, d_ir, m_alpha), 1.0)
        row_angle = _fold_angle(np.einsum("ij,ij->i", unit(d_side), unit(d_ir)))
        bad = meets & (row_angle > max_row_angle)
        rejected["degenerate_row"] = int((bad & ok).sum())
        ok &= ~bad
    if neighbours is not None and len(neighbours):
        # only the candidates still in the running: the others' cut changes nothing
        live = np.flatnonzero(ok)
        cut = np.zeros(len(normals))
        cut[live] = _neighbour_cut(points, supported[live], neighbours, normals[live], offsets[live], d_up[live], d_side[live], max_penetration)
        bad = cut > max_neighbour_cut
        rejected["cuts_neighbour"] = int((bad & ok).sum())
        ok &= ~bad
    quality = (supported * w).sum(1) * (1 - lambda_r + p_r * lambda_r) * (1 - lambda_d + p_d * lambda_d)
    quality = np.where(ok, quality, -np.inf)
    best = int(np.argmax(quality))
    if not np.isfinite(quality[best]) and fixed is None:
        # every candidate rejected: the PCA plane touching the segment
        n = n_ref if (body_side - points.mean(0)) @ n_ref >= 0 else -n_ref
        d = points @ n
        offset = d.min() + max_penetration
        plane = Plane(n * offset, n, 0.0)
        sup = np.abs(d - offset) <= support_distance
        rejected["fallback_pca"] = 1
        return PlaneFitResult(plane, len(normals), rejected, sup)
    if not np.isfinite(quality[best]):
        # every candidate through the fixed points rejected: continue the
        # inner face (``body_side`` direction orthogonalised to the fixed edge)
        rejected["all_rejected"] = 1
        edge = unit(fixed[1] - fixed[0])
        n = unit(fallback_normal - edge * (edge @ fallback_normal))
        d = points @ n - fixed[0] @ n
        plane = Plane(fixed[0], n, 0.0)
        return PlaneFitResult(plane, len(normals), rejected, np.abs(d) <= support_distance)
    n = normals[best]
    plane = Plane(n * offsets[best], n, float(max(quality[best], 0.0)))
    return PlaneFitResult(plane, len(normals), rejected, supported[best])


def _neighbour_cut(points, supported, neighbours, normals, offsets, d_up, d_side, max_penetration):
    """(c,) float64 fraction of neighbour vertices each candidate cuts under its patch."""
    # in-plane coordinates of the supported patch and of the neighbours, (k, c) and (q, c)
    inf = np.inf
    mask = supported.T
    # the extremes over each candidate's supported vertices: its column with the others
    # replaced by +-inf (the same values as a reduction ``where=mask``, about 4x faster)
    pu = points @ d_up.T
    lo_u = np.where(mask, pu, inf).min(axis=0)
    hi_u = np.where(mask, pu, -inf).max(axis=0)
    pv = points @ d_side.T
    lo_v = np.where(mask, pv, inf).min(axis=0)
    hi_v = np.where(mask, pv, -inf).max(axis=0)
    nu = neighbours @ d_up.T
    cut = nu > lo_u  # inside the patch ...
    cut &= nu < hi_u
    nv = neighbours @ d_side.T
    cut &= nv > lo_v
    cut &= nv < hi_v
    depth = neighbours @ normals.T
    depth -= offsets
    cut &= depth < -max_penetration  # ... and deeper than the allowed sink
    return np.count_nonzero(cut, axis=0) / len(neighbours)


def intersect_planes(p: Plane, q: Plane, *, min_angle: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Line of intersection of two planes, or None when nearly parallel.

    Parameters
    ----------
    min_angle : float
        Planes closer than this dihedral angle (rad) count as parallel.

    Returns
    -------
    (point, direction) : ((3,), (3,)) float64, or None
        The point of the line nearest to ``p.point``; a unit direction.
    """
    d = cross(p.normal, q.normal)
    s = np.linalg.norm(d)
    if s < np.sin(min_angle):
        return None
    d = d / s
    # solve for the point on both planes closest to p.point
    A = np.stack([p.normal, q.normal, d])
    rhs = np.array([p.normal @ p.point, q.normal @ q.point, d @ p.point])
    point = np.linalg.solve(A, rhs)
    return point, d
