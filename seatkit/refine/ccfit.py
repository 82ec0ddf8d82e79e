"""The Catmull-Clark surface fit of Sit & Relax (Leimer et al. 2018).

Moves the cage's control points so that its Catmull-Clark *limit surface*
(OpenSubdiv-conformant operators of :mod:`seatkit.subdivision`) meets the
supported body regions. ICP-like:

1. the limit surface is sampled at the refined vertices of ``level``
   (``X = L P``, ``L`` sparse) with limit normals ``N``;
2. every supported body vertex ``b`` (importance above
   ``importance_threshold``, on a body segment that some face of the cage
   supports) takes its closest sample ``c`` (a k-d tree);
3. one sparse linear least-squares solve for the moving control points::

       min  sum_b w_b [ (n_c . (L_c P - b) + o_b)^2 + mu (|L_c P - b|^2) ]  / sum_b w_b
          + fairness * |G (P - P_0)|^2 / v
          + damping  * |P - P_k|^2 / v

   ``w_b`` is the body vertex's importance, multiplied by
   ``penetration_weight`` once the body vertex has been found on the wrong
   side of the surface (inside: ``n_c . (b - x_c) < 0``; it stays marked in
   later iterations, so the active set does not flip-flop); for those the
   target is ``clearance`` below the skin (``o_b``). Every *other* body
   vertex (hands, arms, the top of the thighs...) enters the same term with
   the median importance of the supported vertices as soon as it is found
   inside, so the surface is pushed away from any body part it passes
   through, not only from the supported ones. A vertex still deeper
   than half ``max_penetration`` has its own weight doubled at every
   iteration until it comes out. The first part is the point-to-plane ICP distance, ``mu``
   a small point-to-point share that keeps the tangential drift in check;
   ``G`` is the cage's graph Laplacian, so the fairness term asks for a
   smooth *displacement* of the template's cage ``P_0`` (it keeps the shape
   the template designed where the body does not pull);
4. repeat until the weighted mean distance stops improving by more than
   ``tolerance`` (m) and no supported vertex is deeper inside than
   ``max_penetration``.

Ground and fixed control points do not move. The best iterate (smallest
mean distance among those that meet the penetration limit, else the last
one) is returned; the penetration left is reported in ``meta``, and with
``raise_on_penetration`` a penetration above the limit is a
:class:`~seatkit.errors.SolverError`.

Distances are measured between body vertices and the limit-surface samples
projected onto the sample's tangent plane (point-to-plane); with level 3 the
samples of a 15 cm face are about 2 cm apart.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

from seatkit.errors import SolverError
from seatkit.model import Body, ControlMesh, PressureField
from seatkit.refine.params import refiner_params
from seatkit.refine.quality import mesh_edges

__all__ = [
    "CCFIT_DEFAULTS",
    "FitTargets",
    "supported_targets",
    "surface_distances",
    "fit_report",
    "fit_cage",
    "CatmullClarkFitRefiner",
]

#: Default parameters of ``catmull-clark-fit`` (lengths in m).
CCFIT_DEFAULTS: dict[str, Any] = {
    "level": 3,  # subdivision level of the limit samples
    "importance_threshold": 0.02,  # body vertices with importance above this are supported
    "fairness": 0.05,  # weight of |G (P - P0)|^2 per control point
    "damping": 1e-4,  # weight of |P - P_k|^2 per control point (Levenberg step)
    "point_to_point": 0.1,  # share of the point-to-point distance
    "penetration_weight": 20.0,  # extra weight of body vertices found inside
    "clearance": 0.004,  # m, target gap below a penetrating body vertex
    "max_penetration": 0.005,  # m, allowed depth of a body vertex inside the surface
    "max_distance": 1.0,  # m, correspondences farther than this are ignored
    "max_iterations": 40,
    "tolerance": 1e-4,  # m, stop when the mean distance improves less than this
    "raise_on_penetration": False,  # SolverError when max_penetration cannot be met
}


@dataclass(frozen=True)
class FitTargets:
    """The supported body vertices a fit pulls the surface to.

    Attributes
    ----------
    points : (k, 3) float64
        Body vertex positions, m.
    weights : (k,) float64
        Importance (pressure scaled by its maximum), in (threshold, 1].
    body : (k,) int64
        Which body (index into the bodies) each point comes from.
    vertex : (k,) int64
        Vertex index in its body.
    segments : tuple of tuple of int
        Supported segments per body.
    """

    points: np.ndarray
    weights: np.ndarray
    body: np.ndarray
    vertex: np.ndarray
    segments: tuple


def supported_targets(
    mesh: ControlMesh,
    bodies: Sequence[Body],
    pressures: Sequence[PressureField],
    *,
    threshold: float,
) -> FitTargets:
    """Supported body vertices and their importance.

    A vertex is supported when its importance exceeds ``threshold`` and its
    dominant skinning segment is one the cage supports: the segments listed
    in ``mesh.meta["supported_segments"]`` (a list per body, or one list for
    all) when the template gives them, otherwise those of
    ``mesh.face_segments`` on faces of that person (``face_person`` equal to
    the body index, or -1).

    Parameters
    ----------
    mesh : ControlMesh
    bodies : sequence of Body
    pressures : sequence of PressureField
    threshold : float

    Returns
    -------
    FitTargets

    Raises
    ------
    SolverError
        When no body vertex is supported.
    """
    if len(bodies) != len(pressures):
        msg = f"catmull-clark-fit: {len(bodies)} bodies but {len(pressures)} pressure fields"
        raise SolverError(msg)
    declared = mesh.meta.get("supported_segments")
    pts, wts, which, index, segs_all = [], [], [], [], []
    for k, (body, pressure) in enumerate(zip(bodies, pressures)):
        if declared is not None:
            segs = declared[k] if declared and isinstance(declared[0], (list, tuple)) else declared
            segs = np.unique(np.asarray(segs, dtype=np.int64))
        else:
            mine = (mesh.face_person == k) | (mesh.face_person < 0)
            segs = np.unique(mesh.face_segments[mine])
            segs = segs[segs >= 0]
        importance = np.asarray(pressure.importance, dtype=np.float64)
        dominant = np.argmax(body.weights, axis=1)
        keep = (importance > threshold) & np.isin(dominant, segs)
        idx = np.flatnonzero(keep)
        pts.append(body.vertices[idx])
        wts.append(importance[idx])
        which.append(np.full(idx.size, k, np.int64))
        index.append(idx)
        segs_all.append(tuple(int(s) for s in segs))
    points = np.concatenate(pts) if pts else np.zeros((0, 3))
    if len(points) == 0:
        msg = (
            "catmull-clark-fit: no supported body vertex (importance above "
            f"{threshold} on a segment the cage supports); nothing to fit"
        )
        raise SolverError(msg)
    return FitTargets(
        points=points,
        weights=np.concatenate(wts),
        body=np.concatenate(which),
        vertex=np.concatenate(index),
        segments=tuple(segs_all),
    )


def _graph_laplacian(faces: np.ndarray, n: int) -> sp.csr_matrix:
    """Uniform graph Laplacian ``I - D^-1 A`` of the cage's edges."""
    edges = mesh_edges(faces)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    adjacency = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return (sp.identity(n, format="csr") - sp.diags(1.0 / np.maximum(degree, 1.0)) @ adjacency).tocsr()


def _boundary_samples(ops) -> np.ndarray:
    """(p,) bool: refined vertices on the boundary of the refined mesh."""
    q = ops.faces
    pairs = np.stack([q, np.roll(q, -1, axis=1)], axis=-1).reshape(-1, 2)
    pairs.sort(axis=1)
    uniq, count = np.unique(pairs, axis=0, return_counts=True)
    out = np.zeros(ops.n_points, bool)
    out[uniq[count == 1].ravel()] = True
    return out


def surface_distances(
    samples: np.ndarray, normals: np.ndarray, points: np.ndarray, *, boundary: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance of points to a sampled surface, signed by the surface normal.

    Parameters
    ----------
    samples : (p, 3) float64
        Surface sample positions (limit points).
    normals : (p, 3) float64
        Unit normals at the samples (pointing to the body side).
    points : (k, 3) float64
    boundary : (p,) bool, optional
        Samples on the surface boundary; a point whose closest sample is on
        the boundary and lies beyond it is not "inside".

    Returns
    -------
    closest : (k,) int64
        Index of the closest sample.
    distance : (k,) float64
        Euclidean distance to the closest sample.
    signed : (k,) float64
        ``n . (point - sample)``: negative when the point lies behind the
        surface (inside the furniture).
    """
    tree = cKDTree(samples, balanced_tree=False, compact_nodes=False)  # much faster queries here
    distance, closest = tree.query(points, workers=1)
    signed = np.einsum("kc,kc->k", normals[closest], points - samples[closest])
    if boundary is not None:
        # beyond the boundary the side is undefined: never count it as inside
        signed = np.where(boundary[closest], np.abs(signed), signed)
    return closest.astype(np.int64), distance, signed


def fit_cage(
    mesh: ControlMesh,
    bodies: Sequence[Body],
    pressures: Sequence[PressureField],
    params: Mapping[str, Any] | None = None,
) -> ControlMesh:
    """Fit the limit surface of ``mesh`` to the supported body regions.

    Parameters
    ----------
    mesh : ControlMesh
    bodies : sequence of Body
    pressures : sequence of PressureField
    params : mapping, optional
        Overrides of :data:`CCFIT_DEFAULTS` (after the template's defaults in
        ``mesh.meta["refiners"]["catmull-clark-fit"]``).

    Returns
    -------
    ControlMesh
        Same topology, moved control points; ``meta["catmull-clark-fit"]``
        holds the distances and penetration before and after, iterations
        and time.

    Raises
    ------
    SolverError
        When nothing is supported, the solve diverges (non-finite values or
        a growing distance), or the penetration limit cannot be met.
    """
    from seatkit.subdivision import Cage, build_operators

    start = time.perf_counter()
    p = refiner_params("catmull-clark-fit", CCFIT_DEFAULTS, mesh.meta, params)
    targets = supported_targets(mesh, bodies, pressures, threshold=p["importance_threshold"])
    cage = Cage.from_control_mesh(mesh)
    ops = build_operators(cage, p["level"])
    on_boundary = _boundary_samples(ops)
    limit = ops.limit.tocsr()

    p0 = np.array(mesh.vertices, dtype=np.float64)
    n = len(p0)
    moving = ~(np.asarray(mesh.fixed, bool) | np.asarray(mesh.ground, bool))
    cols = np.flatnonzero(moving)
    m = cols.size
    if m == 0:
        msg = "catmull-clark-fit: every control point is fixed or on the ground; nothing can move"
        raise SolverError(msg)
    # selection of the moving control points, and the fixed part
    select = sp.csr_matrix((np.ones(m), (cols, np.arange(m))), shape=(n, m))
    lap = _graph_laplacian(mesh.faces, n)
    lap_moving = (lap @ select).tocsr()
    fair = p["fairness"] / n * (lap_moving.T @ lap_moving)
    damp = p["damping"] / n * sp.identity(m, format="csr")
    limit_moving = (limit @ select).tocsr()

    # every other body vertex only counts once found inside (penetration over the whole body)
    k_sup = len(targets.points)
    others = []
    for k, body in enumerate(bodies):
        rest = np.ones(len(body.vertices), bool)
        rest[targets.vertex[targets.body == k]] = False
        others.append(np.asarray(body.vertices, dtype=np.float64)[rest])
    b = np.concatenate([targets.points, *others])
    is_target = np.arange(len(b)) < k_sup
    w_base = np.concatenate([targets.weights, np.zeros(len(b) - k_sup)])
    w_inside = float(np.median(targets.weights))
    w_sum = float(w_base.sum())

    def measure(P):
        X = limit @ P
        N = ops.limit_normals(P)
        closest, dist, signed = surface_distances(X, N, b, boundary=on_boundary)
        depth = np.maximum(-signed, 0.0)
        mean = float(np.sum(w_base * np.abs(signed)) / w_sum)
        return X, N, closest, dist, signed, depth, mean

    P = p0.copy()
    X, N, closest, dist, signed, depth, mean = measure(P)
    before = {
        "mean_distance": mean,
        "mean_euclidean_distance": float(dist[:k_sup].mean()),
        "max_penetration": float(depth.max()),
    }
    history = [mean]
    pen_weight = p["penetration_weight"]
    best = (P.copy(), mean, float(depth.max()))
    stall = 0
    iterations = 0
    sticky = np.zeros(len(b), bool)
    multiplier = np.ones(len(b))
    cap = 64.0 * pen_weight
    for iterations in range(1, p["max_iterations"] + 1):
        # a body vertex once found inside keeps its extra weight (no flip-flop
        # of the active set between iterations)
        sticky |= signed < 0.0
        multiplier = np.where(sticky, np.maximum(multiplier, pen_weight), multiplier)
        # vertices still too deep: double their own weight (capped)
        deep = depth > 0.5 * p["max_penetration"]
        multiplier = np.where(deep & (iterations > 1), np.minimum(2.0 * multiplier, cap), multiplier)
        use = dist <= p["max_distance"]
        w = multiplier * np.where(is_target, w_base, w_inside * sticky) * use
        # the data term keeps unit total weight, so the fairness keeps its say
        w = w / max(float(w.sum()), 1e-300)
        # target offset along the normal: those points aim at clearance below the skin
        offset = np.where(sticky, p["clearance"], 0.0)
        n_c = N[closest]
        L_c = limit_moving[closest]  # (k, m)
        fixed_part = limit[closest] @ (P - select @ (select.T @ P))  # contribution of fixed points
        # point-to-plane rows: sum_d n_d (L_c P_d) = n . b - offset - n . fixed
        rhs_plane = np.einsum("kc,kc->k", n_c, b - fixed_part) - offset
        J_plane = sp.hstack([sp.diags(n_c[:, d]) @ L_c for d in range(3)]).tocsr()
        sqw = sp.diags(np.sqrt(w))
        Jw = sqw @ J_plane
        A = (Jw.T @ Jw).tocsr()
        rhs = Jw.T @ (np.sqrt(w) * rhs_plane)
        # point-to-point share, per coordinate (block diagonal)
        Lw = (sp.diags(np.sqrt(p["point_to_point"] * w)) @ L_c).tocsr()
        LtL = (Lw.T @ Lw).tocsr()
        target_pp = b - fixed_part - offset[:, None] * n_c
        P_m = select.T @ P
        P0_m = select.T @ p0
        # fairness on the displacement from the template, damping to the current iterate
        # (fixed points never move, so G (P - P0) = G_m (P_m - P0_m))
        fair_rhs = fair @ P0_m
        blocks = sp.block_diag([LtL + fair + damp] * 3, format="csr")
        system = (A + blocks).tocsc()
        rhs_full = rhs + np.concatenate(
            [Lw.T @ (np.sqrt(p["point_to_point"] * w) * target_pp[:, d]) + fair_rhs[:, d] + (p["damping"] / n) * P_m[:, d] for d in range(3)]
        )
        try:
            solution = spla.spsolve(system, rhs_full)
        except RuntimeError as exc:  # singular factorisation
            msg = f"catmull-clark-fit: the linear solve failed at iteration {iterations}: {exc}"
            raise SolverError(msg) from exc
        if not np.all(np.isfinite(solution)):
            msg = f"catmull-clark-fit: the fit diverged (non-finite control points at iteration {iterations})"
            raise SolverError(msg)
        P = P.copy()
        P[cols] = solution.reshape(3, m).T
        X, N, closest, dist, signed, depth, mean = measure(P)
        history.append(mean)
        max_depth = float(depth.max())
        ok = max_depth <= p["max_penetration"]
        best_ok = best[2] <= p["max_penetration"]
        # keep the closest iterate that meets the penetration limit; until one
        # does, the latest iterate
        if (ok and (not best_ok or mean < best[1])) or not best_ok:
            best = (P.copy(), mean, max_depth)
        improving = history[-2] - mean > p["tolerance"]
        stall = 0 if improving else stall + 1
        if ok and stall >= 2:
            break
    P_best, mean_best, depth_best = best
    if not np.isfinite(mean_best) or mean_best > 10.0 * max(before["mean_distance"], 1e-3):
        msg = (
            f"catmull-clark-fit: the fit diverged: mean distance {before['mean_distance']:.4g} m "
            f"-> {mean_best:.4g} m"
        )
        raise SolverError(msg)
    if p["raise_on_penetration"] and depth_best > p["max_penetration"]:
        msg = (
            f"catmull-clark-fit: a supported body vertex stays {depth_best * 1000:.1f} mm inside the "
            f"surface (max_penetration {p['max_penetration'] * 1000:.1f} mm) after {iterations} iterations"
        )
        raise SolverError(msg)
    X, N, closest, dist, signed, depth, mean = measure(P_best)
    meta = dict(mesh.meta)
    meta["catmull-clark-fit"] = {
        "before": before,
        "after": {
            "mean_distance": mean,
            "mean_euclidean_distance": float(dist[:k_sup].mean()),
            "max_penetration": float(depth.max()),
        },
        "supported_vertices": int(k_sup),
        "supported_segments": [list(s) for s in targets.segments],
        "iterations": int(iterations),
        "history": history,
        "seconds": time.perf_counter() - start,
        "params": p,
    }
    return replace(mesh, vertices=P_best, meta=meta)


class CatmullClarkFitRefiner:
    """The ``catmull-clark-fit`` refiner: Sit & Relax's limit-surface fit."""

    name = "catmull-clark-fit"
    description = "Catmull-Clark limit surface fitted to the supported body regions (Sit & Relax)"

    def refine(
        self,
        mesh: ControlMesh,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        *,
        params: Mapping[str, Any] | None = None,
    ) -> ControlMesh:
        """Return the fitted cage (same topology)."""
        return fit_cage(mesh, bodies, pressures, params)


def fit_report(
    mesh: ControlMesh,
    bodies: Sequence[Body],
    pressures: Sequence[PressureField],
    *,
    threshold: float = CCFIT_DEFAULTS["importance_threshold"],
    level: int = 4,
) -> dict[str, float]:
    """How well the limit surface of ``mesh`` meets the bodies.

    Parameters
    ----------
    mesh : ControlMesh
    bodies : sequence of Body
    pressures : sequence of PressureField
    threshold : float
        Importance above which a body vertex counts as supported.
    level : int
        Subdivision level of the limit samples (4: about 1 cm apart).

    Returns
    -------
    dict
        ``mean_distance`` (m, importance-weighted point-to-plane distance of
        the supported vertices), ``mean_euclidean_distance`` (m, unweighted
        distance to the closest limit sample), ``max_penetration`` (m, the
        deepest *any* body vertex lies behind the surface; vertices whose
        closest sample is on the surface boundary are not inside),
        ``supported_vertices``.
    """
    from seatkit.subdivision import Cage, build_operators

    targets = supported_targets(mesh, bodies, pressures, threshold=threshold)
    ops = build_operators(Cage.from_control_mesh(mesh), level)
    X = ops.limit_points(mesh.vertices)
    N = ops.limit_normals(mesh.vertices)
    boundary = _boundary_samples(ops)
    _, dist, signed = surface_distances(X, N, targets.points, boundary=boundary)
    every = np.concatenate([np.asarray(b.vertices, dtype=np.float64) for b in bodies])
    _, _, signed_all = surface_distances(X, N, every, boundary=boundary)
    return {
        "mean_distance": float(np.sum(targets.weights * np.abs(signed)) / targets.weights.sum()),
        "mean_euclidean_distance": float(dist.mean()),
        "max_penetration": float(max(0.0, -signed_all.min())),
        "supported_vertices": int(len(targets.points)),
    }
