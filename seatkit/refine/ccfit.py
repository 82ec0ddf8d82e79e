"""The Catmull-Clark surface fit of Sit & Relax (Leimer et al. 2018).

Moves the cage's control points so that its Catmull-Clark *limit surface*
(OpenSubdiv-conformant operators of :mod:`seatkit.subdivision`) meets the
supported body regions without passing through the body. ICP-like:

1. the limit surface is sampled at the refined vertices of ``level``
   (``X = L P``, ``L`` sparse) with limit normals ``N``;
2. every supported body vertex (importance above ``importance_threshold``,
   on a body segment that some face of the cage supports) is a target
   ``b = v + clearance * n_v``: the skin offset outwards by the clearance
   along its normal; it takes its closest sample ``c`` (a k-d tree), and the
   pair is used only when the skin faces the surface there
   (``n_v . n_c < -min_facing``): a support holds skin that faces it, and
   pairing, say, the front of a shin with the seat below the knee would wrap
   the surface around the limb;
3. penetration is measured from the body side, with the exact distance to
   the closed skin (:class:`seatkit.geometry.skin.SkinDistance`: closest point on the
   skin's triangles, inside or outside by the angle-weighted pseudo-normal).
   The probes are the limit points, and in a polishing phase (only when
   needed) also the refined quads' centres, which catch thin body parts
   poking through between the limit points. The floor (y = 0) is an
   obstacle too: probes below it are lifted to it. Only the probes that
   can be within the clearance of a skin are asked (the skin's
   open-space grid gives a lower bound on the distance,
   :meth:`~seatkit.geometry.skin.SkinDistance.clear_of`): a probe farther
   out takes no part in the step, so the iterates are the same;
4. one sparse linear least-squares solve for the moving control points::

       min  sum_b w_b [ (n_c . (L_c P - b))^2 + mu |L_c P - b|^2 ] / sum_b w_b
          + sum_{x in A} w_pen (1 + min(depth_x / clearance, 4)) (g_x . (L_x P - q_x) - clearance)^2 / sum_b w_b
          + fairness * |G (P - P_0)|^2 / v  +  damping * |P - P_k|^2 / v

   ``w_b`` is the importance, ``A`` the probes inside the body or closer to
   the skin than the clearance (below the floor: lifted to it, with no
   clearance), pulled out to the clearance along a way out
   ``g_x`` from the skin point ``q_x`` (``w_pen = penetration_weight * mean
   importance``, deeper probes weigh more); ``G`` is the cage's graph
   Laplacian, so the fairness asks for a smooth *displacement* of the
   template's cage ``P_0``. The way out of a shallow probe is the skin
   distance's gradient (the nearest side of the skin). A probe deeper than
   half the clearance leaves *backwards*, along minus the surface normal,
   to where that ray leaves the body (``retreat``): a support holds the body
   on its front, and when a sheet of the surface cuts through a limb (a
   shin, an ankle crossed over the other) every probe of the sheet then
   agrees on the way out, where the nearest side splits the sheet, half
   pulled to each side of the limb, and the fit stalls inside it. Where the
   backward way is long, or runs against the skin's nearest side (the
   surface faces away from the body there), the nearest side is kept;
   A supported skin vertex *behind* the surface (a crease the surface
   bridges, as between the thighs: no probe is inside the body, yet the
   skin at the bottom of the crease is inside the furniture; a sole on the
   floor under a surface a few mm above it) weighs as much as a probe
   inside the body, until the surface is below it;
5. a trust region: the step is shortened until no control point moves more
   than ``max_step`` (or than the current mean distance, while the surface is
   still far, as a flat patch rising from the floor). Correspondences,
   normals and ways out hold only near the current surface; without it a
   control point could jump tens of centimetres and tangle the cage;
6. repeat until the weighted mean distance stops improving by more than
   ``tolerance`` (m) and no probe is deeper in the body than
   ``max_penetration`` (3 mm at the probes leaves 2 mm for the surface
   between them, for the 5 mm the evaluation allows), or ``max_iterations``
   (then up to ``extra_iterations`` more while the limit is not met and the
   deepest probe still gets shallower).

Ground and fixed control points do not move. The best iterate (smallest
mean distance among those within the penetration limit, else the
shallowest) is kept; the penetration left is reported in ``meta``, and
with ``raise_on_penetration`` a penetration above the limit is a
:class:`~seatkit.errors.SolverError`. Last, the kept surface is measured
as the evaluation measures it (surface below the skin, body vertices
inside the furniture, ``meta["catmull-clark-fit"]["final_depth"]``);
deeper than ``surface_limit`` (5 mm), it is refitted with a tighter probe
target (and, when a body vertex lies too deep inside the furniture, with
every body vertex guarded: one the fit does not pull to, a hand hanging
under the edge of the seat, pushes the surface back past it like a probe
inside the body; such a refit starts from the fit it answers; a fit caught
in the body from its approach on is not refitted). The fit returns the refit closest to the limit and
judges nothing: the 5 mm guarantee is the design search's acceptance
check (:mod:`seatkit.search`), which also offers :func:`push_out` (the
offending spots' control points pushed away from the body, without the
pull to the skin) as a candidate of its own.
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
from seatkit.geometry.closest import row_norms
from seatkit.geometry.normals import kept_vertex_normals
from seatkit.geometry.skin import SkinDistance
from seatkit.geometry.surface import SurfaceQuery, body_depth_in_surface, body_inside_furniture, inside_furniture, surface_depth_in_body
from seatkit.model import Body, ControlMesh, PressureField, Surface
from seatkit.pressure.contact import supported_vertices
from seatkit.options import Option, defaults
from seatkit.params import refiner_params
from seatkit.refine.quality import mesh_edges
from seatkit.side import beside
from seatkit.stopping import checkpoint

__all__ = [
    "CCFIT_DEFAULTS",
    "CCFIT_OPTIONS",
    "FitTargets",
    "supported_targets",
    "surface_distances",
    "fit_report",
    "fit_cage",
    "CatmullClarkFitRefiner",
    "final_depths",
    "push_out",
]

#: Options of ``catmull-clark-fit`` (lengths in m): its parameters' one declaration.
CCFIT_OPTIONS: dict[str, Option] = {
    "level": Option("count", "subdivision level of the limit samples", 3, "", 1, 4),
    "importance_threshold": Option("number", "body vertices with importance above this are supported", 0.02, "1", 0.0, 1.0),
    "fairness": Option("number", "weight of |G (P - P0)|^2 per control point", 0.05, "1", 0.0, 1e6),
    "damping": Option("number", "weight of |P - P_k|^2 per control point (Levenberg step)", 1e-4, "1", 0.0, 1e6),
    "point_to_point": Option("number", "share of the point-to-point distance", 0.1, "1", 0.0, 1.0),
    "penetration_weight": Option("number", "weight of a surface sample inside the body, relative to the mean importance", 100.0, "1", 0.0, 1e9),
    "clearance": Option("number", "gap kept between the surface and the skin", 0.006, "m", 0.0, 0.1),
    "max_penetration": Option("number", "allowed depth of a probe inside the body", 0.003, "m", 0.0, 0.1),
    "min_facing": Option("number", "a correspondence needs skin normal . surface normal below -min_facing", 0.2, "1", -1.0, 1.0),
    "max_distance": Option("number", "correspondences farther than this are ignored", 1.0, "m", 0.0, 100.0),
    "retreat": Option("bool", "probes inside the body leave it backwards along the surface normal", True),
    "retreat_agreement": Option("number", "... unless that way runs against the skin's nearest way out (cosine below minus this)", 0.25, "1", -1.0, 1.0),
    "max_step": Option("number", "the farthest a control point moves in one iteration", 0.03, "m", 1e-6, 10.0),
    "max_iterations": Option("count", "iterations of the fit", 20, "", 0, 100000),
    "polish_iterations": Option("count", "extra iterations with denser penetration probes, when needed", 8, "", 0, 100000),
    "extra_iterations": Option("count", "more iterations of a phase while the penetration limit is not met and the depth still falls", 60, "", 0, 100000),
    "tolerance": Option("number", "stop when the mean distance improves less than this", 1e-4, "m", 0.0, 1.0),
    "raise_on_penetration": Option("bool", "SolverError when max_penetration cannot be met", False),
    "surface_limit": Option("number", "refit with tighter probes while the final surface (level 4) reaches deeper into a body, or a body vertex deeper inside the furniture; the design search rejects a design over it; 0: off", 0.005, "m", 0.0, 1.0),
}

#: Default parameters of ``catmull-clark-fit`` (from :data:`CCFIT_OPTIONS`).
CCFIT_DEFAULTS: dict[str, Any] = defaults(CCFIT_OPTIONS)

#: Iterations without a deeper-probe improvement after which the extra iterations stop.
_DEPTH_PATIENCE = 5

#: When set, called (keyword arguments) after every step's solve with that step's state, for
#: benchmarks/ccfit_steps.py: where the solved step goes, and which rows ask for it. None in a build.
_observe = None


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


#: Samples along a probe's way out of the body: depth * scale + extra (m).
_RETREAT_SCALE = np.array([1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.0, 2.0])
_RETREAT_EXTRA = np.array([0.0, 0.002, 0.004, 0.006, 0.009, 0.012, 0.016, 0.02])


#: Probes farther than this outside a body's bounding box are not asked
#: about that body: their depth is at most minus this, m.
_FAR = 0.05


def skin_depth(skins: Sequence[SkinDistance], points: np.ndarray):
    """Depth of points in the deepest of several bodies (see :class:`SkinDistance`).

    Each body is asked only about the points near its bounding box; a point
    near none gets depth ``-_FAR`` (a bound: it is at least that far outside)
    with placeholder foot and direction, which no caller uses at that depth.
    """
    depth = np.full(len(points), -_FAR)
    foot = np.array(points, dtype=np.float64, copy=True)
    out = np.zeros_like(foot)
    out[:, 1] = 1.0
    for skin in skins:
        lo, hi = skin.bounds[0] - _FAR, skin.bounds[1] + _FAR
        x, y, z = points.T  # (column by column: a reduction along the short axis is several times slower)
        near = np.flatnonzero((x > lo[0]) & (x < hi[0]) & (y > lo[1]) & (y < hi[1]) & (z > lo[2]) & (z < hi[2]))
        if not near.size:
            continue
        d, q, g = skin.query(np.take(points, near, axis=0))
        deeper = d > depth[near]
        k = near[deeper]
        depth[k], foot[k], out[k] = d[deeper], q[deeper], g[deeper]
    return depth, foot, out


def skin_depth_near(skins: Sequence[SkinDistance], points: np.ndarray, near: float):
    """:func:`skin_depth` where it can be above ``-near``; elsewhere a bound below it.

    Points the skins' open-space grids (:meth:`SkinDistance.clear_of`) put
    at least ``near`` outside every body are not asked: their depth is
    minus that bound, their skin point and way out placeholders.
    :func:`skin_depth` would put them at ``-near`` or beyond too (``near``
    at most :attr:`SkinDistance.EXACT_WITHIN`): its exact answer is the
    distance to the closest triangle it finds, never nearer than the true
    one; its estimate is used only beyond ``EXACT_WITHIN``; a point far
    from a body's box gets ``-_FAR``. A ``near`` beyond ``EXACT_WITHIN`` (a
    clearance above 15 mm) asks every point: :func:`skin_depth` itself.
    """
    if near > SkinDistance.EXACT_WITHIN:
        return skin_depth(skins, points)
    clear = np.min([skin.clear_of(points) for skin in skins], axis=0) if skins else np.full(len(points), _FAR)
    ask = np.flatnonzero(clear < near)
    depth = -clear
    foot = np.array(points, dtype=np.float64, copy=True)
    out = np.zeros_like(foot)
    out[:, 1] = 1.0
    if ask.size:
        depth[ask], foot[ask], out[ask] = skin_depth(skins, points[ask])
    return depth, foot, out


#: The samples of a way out asked at once, in turn, each batch only for the rays still inside
#: (a library pose's probes: 15% leave at the first sample, 78% at the second, 7% later).
_RETREAT_BATCHES = ((0, 2), (2, 4), (4, len(_RETREAT_SCALE)))


def _depths_to_exit(skins: Sequence[SkinDistance], ray: np.ndarray) -> np.ndarray:
    """(k, s) depths of the samples ``ray`` (k, s, 3) along each ray, up to its first sample outside every body.

    The samples of a ray after its first outside one are not asked (they
    read as outside, ``-inf``): the way out uses the depths up to the exit
    only. Each sample's depth is :func:`skin_depth`'s.
    """
    k, s, _ = ray.shape
    dd = np.full((k, s), -np.inf)
    still = np.arange(k)  # rays with no sample outside yet
    for lo, hi in _RETREAT_BATCHES:
        if not still.size:
            break
        dd[still, lo:hi] = skin_depth(skins, ray[still, lo:hi].reshape(-1, 3))[0].reshape(still.size, hi - lo)
        still = still[~(dd[still, lo:hi] <= 0.0).any(axis=1)]
    return dd


def _gram_by_coordinate(directions: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``M`` and ``M.T @ M`` for ``M = [d_x * rows, d_y * rows, d_z * rows]`` (unknowns stacked by coordinate).

    ``directions`` (k, 3) scales each row of ``rows`` (k, m) per coordinate.
    ``M`` is written into one array (no ``hstack`` of three copies); the
    product is numpy's ``a.T @ a`` (a symmetric rank-k update).
    """
    k, m = rows.shape
    M = np.empty((k, 3 * m))
    for d in range(3):
        np.multiply(directions[:, d : d + 1], rows, out=M[:, d * m : (d + 1) * m])
    return M, M.T @ M


def _boundary_samples(ops) -> np.ndarray:
    """(p,) bool: refined vertices on the boundary of the refined mesh."""
    q = ops.faces
    a, b = q.ravel(), np.roll(q, -1, axis=1).ravel()
    n = ops.n_points
    # an edge as one integer key (one row each way round the quads)
    key = np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)
    uniq, count = np.unique(key, return_counts=True)
    once = uniq[count == 1]
    out = np.zeros(n, bool)
    out[once // n] = True
    out[once % n] = True
    return out


def _sample_tree(samples: np.ndarray) -> cKDTree:
    """The k-d tree of a surface's samples that :func:`surface_distances` searches."""
    return cKDTree(samples, balanced_tree=False, compact_nodes=False)  # much faster queries here


def _correspondences(samples: np.ndarray, normals: np.ndarray, points: np.ndarray, boundary: np.ndarray) -> tuple:
    """The samples' k-d tree and :func:`surface_distances` searched in it."""
    tree = _sample_tree(samples)
    return tree, surface_distances(samples, normals, points, boundary=boundary, tree=tree)


def surface_distances(
    samples: np.ndarray, normals: np.ndarray, points: np.ndarray, *, boundary: np.ndarray | None = None, tree: cKDTree | None = None
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
    tree : cKDTree, optional
        The samples' k-d tree as :func:`_sample_tree` makes it, when the
        caller has one already (not made again).

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
    tree = _sample_tree(samples) if tree is None else tree
    distance, closest = tree.query(points, workers=1)
    # (np.take gathers rows several times faster than indexing does)
    signed = np.einsum("kc,kc->k", np.take(normals, closest, axis=0), points - np.take(samples, closest, axis=0))
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
        Overrides of :data:`CCFIT_DEFAULTS` (declared in :data:`CCFIT_OPTIONS`).

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
    from threadpoolctl import threadpool_limits

    # small dense blocks: multithreaded BLAS only adds contention (3-8x
    # slower on a busy 2-core machine)
    with threadpool_limits(limits=1):
        return _fit_cage(mesh, bodies, pressures, params)


#: Fits with a tighter probe target tried when the final surface exceeds ``surface_limit``.
_REPAIR_ROUNDS = 2
#: The tightest probe target a repair round asks for, m.
_MIN_PROBE_TARGET = 0.0005


def _fit_cage(mesh, bodies, pressures, params) -> ControlMesh:
    """The fit, refitted with tighter probes while its final surface is deeper than ``surface_limit``.

    The probes catch the surface inside the body at its samples; a body
    vertex can still lie a little deeper between them. When the final
    surface exceeds the limit, the fit is run again with the probe target
    lowered by the excess (and 1 mm more), at most ``_REPAIR_ROUNDS`` times.
    When a body vertex lies deeper inside the furniture than the limit, the
    refits also *guard* the body vertices the fit does not pull to (a hand
    hanging beside the seat, under its edge): one inside the furniture (the
    evaluation's ray parity, on the fit's tessellation, every iteration)
    pushes its closest limit sample back past it by the clearance, as
    firmly as a probe inside the body, and counts in the depth the fit
    judges its iterates by. (The closest sample's side alone calls about
    2,000 vertices of a seated body "behind" the surface, up to 23 cm deep,
    and those rows pushed the surface into the body.)

    A guarded refit starts from the fit closest to the limit (still faired
    towards the cage), unless that fit's own probes stayed deeper in the
    body than the limit (:func:`_refit_start`): from the cage it would
    first repeat the approach to the body, about half its iterations, with
    every guarded vertex tested on the way. A refit from the closest fit
    that comes no closer is followed by one from the cage; any other refit
    starts from the cage. No refit follows a fit caught in the body from
    its approach on (:func:`_caught_throughout`).

    Returns the first fit within the limit, else the one closest to it:
    the fit judges nothing. Its ``meta["catmull-clark-fit"]["final_depth"]``
    is what the design search's acceptance check reads (:mod:`seatkit.search`).
    """
    p = refiner_params("catmull-clark-fit", CCFIT_OPTIONS, params)
    params = dict(params or {})
    target = p["max_penetration"]
    rounds = []
    guard = False
    closest = None
    stalled = False  # the last refit started from the closest fit and came no closer: the next starts from the cage
    shared = {}  # what the rounds share (the problem, the cage's measurement): see _fit_once
    for round_ in range(_REPAIR_ROUNDS + 1):
        start_from = None if stalled else _refit_start(closest, guard, p["surface_limit"])
        out = _fit_once(mesh, bodies, pressures, {**params, "max_penetration": target}, guard=guard, start_from=start_from, shared=shared)
        report = out.meta["catmull-clark-fit"]
        final = report["final_depth"]
        if final is None or max(final.values()) <= p["surface_limit"]:
            closest = out
            break
        rounds.append({"probe_target": target, "guard": guard, **final})
        closer = closest is None or max(final.values()) < max(closest.meta["catmull-clark-fit"]["final_depth"].values())
        stalled = start_from is not None and not closer
        if closer:
            closest = out
        if _caught_throughout(report, p["surface_limit"]):
            rounds[-1]["caught_throughout"] = True
            break  # a refit from the cage repeats this approach and stays as deep: none is run
        # a body part the cage does not support inside the furniture (a
        # hanging hand under the edge of the seat): the refits keep every
        # body vertex out, not only the supported ones
        guard = guard or final["body_in_surface"] > p["surface_limit"]
        excess = max(final.values()) - p["surface_limit"]
        if target <= _MIN_PROBE_TARGET:
            break
        target = max(target - excess - 0.001, _MIN_PROBE_TARGET)
    if rounds:
        report = closest.meta["catmull-clark-fit"]
        report["repair_rounds"] = rounds
        report["params"] = {**report["params"], "max_penetration": p["max_penetration"]}
    return closest


def _caught_throughout(report: Mapping[str, Any], limit: float) -> bool:
    """The fit of ``report`` is caught in the body from its approach on: its probes end deeper than ``limit`` and no iterate came within it.

    Such a fit passed through the body on its way to it and never got out
    (``depth_history``, the depth each iterate is judged by, never at or
    below ``limit``). A refit after it would start from the cage
    (:func:`_refit_start`) and repeat that approach with tighter probes:
    on the drawn-pose benchmark it ended as deep each time (docs/templates.md,
    "What a rejected candidate costs"). A fit caught only later (one of its
    iterates within the limit, the probes caught again while polishing)
    is refitted: from the cage its refit can stay out.
    """
    history = report.get("depth_history") or ()
    return report["after"]["max_penetration"] > limit and bool(history) and min(history) > limit


def _refit_start(closest: ControlMesh | None, guard: bool, limit: float):
    """Where a refit starts: None (the cage), or for a guarded refit the control points of the fit closest to the limit.

    A guarded refit answers body vertices inside the furniture that the fit
    does not pull to (a hand under the seat's edge): the fit it starts from
    is right but where it closes over them. Not when that fit's own probes
    stayed deeper in the body than ``limit``: it is caught in the body, and a
    refit from it stays there. A refit with tighter probes alone starts from
    the cage (from the fit, the probes it passed hold it where it is).
    """
    if closest is None or not guard or closest.meta["catmull-clark-fit"]["after"]["max_penetration"] > limit:
        return None
    return closest.vertices


def push_out(mesh: ControlMesh, bodies: Sequence[Body]) -> ControlMesh | None:
    """A fitted cage over its ``surface_limit`` with the offending spots pushed away from the body (:func:`_push_out`); None when that fails.

    ``mesh`` is the surface fit's result (its ``meta["catmull-clark-fit"]``
    gives the parameters and the depths). The repaired cage's report says
    from which depths, in how many steps (``pushed_out``) and its new
    ``final_depth``.
    """
    report = mesh.meta.get("catmull-clark-fit")
    if not report or not report.get("final_depth"):
        return None
    p = report["params"]
    pushed = _push_out(mesh, bodies, p)
    if pushed is None:
        return None
    out, final, steps = pushed
    report = dict(report)
    report["pushed_out"] = {"steps": steps, "from": dict(report["final_depth"])}
    report["final_depth"] = final
    return replace(out, meta={**out.meta, "catmull-clark-fit": report})


def final_depths(mesh: ControlMesh, bodies: Sequence[Body], level: int = CCFIT_DEFAULTS["level"]) -> dict[str, float]:
    """How deep the limit surface of ``mesh`` reaches into the bodies (``surface_in_body``) and they into it (``body_in_surface``), m."""
    return _final_depths(mesh, bodies, level)


#: Steps of the last local repair (:func:`_push_out`).
_PUSH_STEPS = 6
#: Weight of the displacement's fairness over the cage's edges in the local repair, against a unit damping.
_PUSH_FAIRNESS = 1.0
#: Weight of an offending spot's row in the local repair, against a unit damping (1e4 asks the rows
#: almost exactly: one step moved the surface 22 cm to take a fingertip 5 mm out; 100: 3-13 mm).
_PUSH_WEIGHT = 100.0


def _samples_and_centres(quads: np.ndarray, n_samples: int) -> sp.csr_matrix:
    """(n_samples + len(quads), n_samples): every limit sample, then each refined quad's centre (its corners' mean)."""
    centres = sp.csr_matrix(
        (np.full(quads.size, 0.25), (np.repeat(np.arange(len(quads)), 4), quads.ravel())), shape=(len(quads), n_samples)
    )
    return sp.vstack([sp.identity(n_samples, format="csr"), centres]).tocsr()


def _push_out(mesh: ControlMesh, bodies: Sequence[Body], p: Mapping[str, Any]) -> tuple | None:
    """The last local repair of a fit over the limit: push the offending spots out, or ``None``.

    The fit balances its pull to the supported skin against its probes;
    where that balance leaves a spot over ``surface_limit`` (fingertips on a
    thigh reaching the seat under it, a hand under the seat's side wall),
    this moves the control points under the offending spots away from the
    body, with no pull to the skin. A spot is, on each tessellation
    ``_final_depths`` measures, a limit sample closest to a body vertex
    inside the furniture, or a probe (sample or quad centre) inside a body,
    deeper than ``max_penetration`` minus 1 mm; it asks to move back by its
    depth beyond that, along minus its surface normal (a probe whose way
    out of the skin is against that, by more than ``retreat_agreement``:
    along the skin's way out, as the fit's retreat). A limit sample below
    the floor asks to come back up to it. Each moving control point moves
    along minus the surface normal at its own limit point (one unknown per
    control point); the least-squares step weighs the spots' rows
    (:data:`_PUSH_WEIGHT`) against a unit damping of the moves and their
    fairness over the cage's edges (:data:`_PUSH_FAIRNESS`), so that control
    points no spot depends on stay where they are. The cage is measured as
    the guarantee measures it after each step: the first within the limit
    is returned with its depths and the steps taken, ``(mesh, final_depth,
    steps)``; ``None`` when a step does not bring the deepest figure down
    (the spots push against each other: a hand squeezed between the thigh
    and the side wall) or after :data:`_PUSH_STEPS` steps.
    """
    from seatkit.subdivision import Cage, build_operators

    settle = max(p["max_penetration"] - 0.001, 0.0)
    P = np.array(mesh.vertices, dtype=np.float64)
    n = len(P)
    cols = np.flatnonzero(~(np.asarray(mesh.fixed, bool) | np.asarray(mesh.ground, bool)))
    m = cols.size
    if m == 0:
        return None
    cage = Cage.from_control_mesh(mesh)
    levels = []
    for lv in sorted({p["level"], 4}):
        ops = build_operators(cage, lv)
        spots = _samples_and_centres(ops.faces, ops.n_points)
        levels.append((lv, ops, spots, (spots @ ops.limit).tocsr()))
    skins = [SkinDistance.of(bd.vertices, bd.faces) for bd in bodies]
    lap = _graph_laplacian(mesh.faces, n)[:, cols]
    base = (sp.identity(m, format="csr") + _PUSH_FAIRNESS * (lap.T @ lap)).toarray()
    worst = max((mesh.meta.get("catmull-clark-fit", {}).get("final_depth") or {"": np.inf}).values())
    for step_no in range(_PUSH_STEPS):
        # each control point moves along minus the surface normal at its own
        # limit point (the first limit points are the control points'), away
        # from the body: one unknown per control point
        limits = [ops.limit_points(P) for _, ops, _, _ in levels]
        normals = [ops.limit_normals(P, X) for (_, ops, _, _), X in zip(levels, limits)]
        away = -normals[-1][cols]
        rows, needs = [], []
        for (lv, ops, spots, probes), X, N in zip(levels, limits, normals):
            Y = probes @ P
            NY = spots @ N
            NY /= np.maximum(row_norms(NY)[:, None], 1e-300)
            surface = Surface(X, N, ops.faces, lv)
            need = np.zeros(len(Y))
            # body vertices inside the furniture: their closest sample goes back past them
            tree = None  # the samples' k-d tree, made when a vertex needs it
            for body in bodies:
                # (the final check of these control points found them already: kept by content)
                inside, d = body_inside_furniture(surface, body)
                if inside.size:
                    held = np.take(body.vertices, inside, axis=0)
                    deep = d > settle
                    if deep.any():
                        tree = cKDTree(X) if tree is None else tree
                        _, s = tree.query(held[deep])
                        np.maximum.at(need, s, d[deep] - settle)
            # probes inside a body: back out of it, along minus the normal as
            # the fit's retreat, unless that is against the skin's nearest
            # way out (the surface faces away from the body there: a flap
            # beside the hip), then that way
            depth, _, out = skin_depth_near(skins, Y, p["clearance"])
            against = (depth > need) & (np.einsum("kc,kc->k", out, -NY) < -p["retreat_agreement"])
            way = np.where(against[:, None], out, -NY)
            need = np.maximum(need, depth - settle)
            k = np.flatnonzero(need > 0)
            if k.size:
                rows.append((probes[k][:, cols].toarray(), way[k]))
                needs.append(need[k])
            # the floor is an obstacle too: a spot below it goes back up to it
            k = np.flatnonzero(Y[:, 1] < 0.0)
            if k.size:
                rows.append((probes[k][:, cols].toarray(), np.tile([0.0, 1.0, 0.0], (k.size, 1))))
                needs.append(-Y[k, 1])
        if not rows:
            break
        # each spot's displacement along its way, per control point's move along ``away``
        A = np.concatenate([r * (g @ away.T) for r, g in rows])
        need = np.concatenate(needs)
        t = np.linalg.solve(base + _PUSH_WEIGHT * (A.T @ A), _PUSH_WEIGHT * (A.T @ need))
        P = P.copy()
        P[cols] += t[:, None] * away
        final = _final_depths(replace(mesh, vertices=P), bodies, p["level"])
        if max(final.values()) <= p["surface_limit"]:
            return replace(mesh, vertices=P), final, step_no + 1
        if max(final.values()) >= worst:
            return None
        worst = max(final.values())
    return None


def _fit_problem(mesh, bodies, pressures, p) -> tuple:
    """What a fit of ``mesh`` to the bodies asks, whatever its probe target: its targets, operators, probes and the fixed parts of its normal equations.

    The same for every round of one fit (:func:`_fit_cage`: the rounds
    differ in their probe target, ``max_penetration``, and guard): made once
    there. See :func:`_fit_once` for what each part is.
    """
    from seatkit.subdivision import Cage, build_operators

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

    # The body side of the fit. Penetration is measured from the body, whose
    # closed skin has a well-defined inside: this stays meaningful where the
    # surface folds or wraps (the surface's own normals do not).

    skin_n = np.concatenate([kept_vertex_normals(bd.vertices, bd.faces) for bd in bodies])
    skins = [SkinDistance.of(bd.vertices, bd.faces) for bd in bodies]
    # supported targets: the skin offset by the clearance along its normal
    owner_offset = np.cumsum([0] + [len(bd.vertices) for bd in bodies])[:-1]
    target_n = skin_n[owner_offset[targets.body] + targets.vertex]
    b = targets.points + p["clearance"] * target_n
    # the soles rest on the floor (y = 0): a target offset below it would pull
    # the surface under the ground
    b[:, 1] = np.maximum(b[:, 1], 0.0)
    w_base = targets.weights
    w_sum = float(w_base.sum())
    w_pen = p["penetration_weight"] * float(np.mean(w_base))

    # penetration probes: the limit points (a probe inside the body means the
    # surface passes through it); a polishing phase adds the centres of the
    # refined quads, which catch thin body parts poking through between them
    # probes as combinations of the limit samples (their normals are the
    # same combinations of the samples' normals), per phase
    sample_probes = (sp.identity(limit.shape[0], format="csr"), _samples_and_centres(ops.faces, limit.shape[0]))
    with_centres = (sample_probes[1] @ limit).tocsr()
    phases = (
        (limit, limit_moving, p["max_iterations"]),
        (with_centres, (with_centres @ select).tocsr(), p["polish_iterations"]),
    )
    # The normal equations of one step, unknowns stacked by coordinate
    # (x of the m moving points, then y, then z). Targets sharing a limit
    # sample are summed first (their rows differ only in the right-hand
    # side); small cages (up to 150 moving points: a chair has about 70, a
    # bench for two about 110) are assembled and solved densely, 1.3-1.5x
    # faster than sparse products of this size; larger ones stay sparse (a
    # bench for six, 260 moving points: 2.6 s sparse, 4.9 s dense).
    P0_m = select.T @ p0
    fair_rhs = fair @ P0_m
    fixed_X = limit @ (p0 - select @ P0_m)  # the fixed control points' share of every sample
    probe_fixed = [ph[0] @ (p0 - select @ P0_m) for ph in phases]
    dense_step = 3 * m <= 450
    limit_rows = probe_rows = None  # dense steps only: the rows of the moving control points (the probes' on first use)
    if dense_step:
        limit_rows = limit_moving.toarray()
        probe_rows = [None, None]
        base = np.kron(np.eye(3), (fair + damp).toarray())
    else:
        base = sp.block_diag([fair + damp] * 3, format="csr")
    base_rhs = np.concatenate([fair_rhs[:, d] for d in range(3)])
    return (
        targets, ops, on_boundary, limit, p0, n, cols, m, select, fair, skins, owner_offset, target_n, b,
        w_base, w_sum, w_pen, sample_probes, phases, fixed_X, probe_fixed, dense_step, limit_rows, probe_rows, base, base_rhs,
    )


def _fit_once(mesh, bodies, pressures, params, *, guard: bool = False, start_from: np.ndarray | None = None, shared: dict | None = None) -> ControlMesh:
    """One fit (see :func:`_fit_cage`).

    ``shared`` is a dict the rounds of one fit pass (the same cage, bodies
    and parameters but the probe target): the first round keeps there what
    does not depend on the probe target or the guard (the problem,
    :func:`_fit_problem`, and the measurement of the cage itself), and the
    later ones read it.
    """
    start = time.perf_counter()
    p = refiner_params("catmull-clark-fit", CCFIT_OPTIONS, params)
    if shared is not None:
        # rounds whose parameters differ in more than the probe target share nothing
        shared = shared.setdefault(repr(sorted((k, v) for k, v in p.items() if k != "max_penetration")), {})
    problem = shared.get("problem") if shared is not None else None
    if problem is None:
        problem = _fit_problem(mesh, bodies, pressures, p)
        if shared is not None:
            shared["problem"] = problem
    (
        targets, ops, on_boundary, limit, p0, n, cols, m, select, fair, skins, owner_offset, target_n, b,
        w_base, w_sum, w_pen, sample_probes, phases, fixed_X, probe_fixed, dense_step, limit_rows, probe_rows, base, base_rhs,
    ) = problem
    k_sup = len(b)
    # the guarded body vertices: every vertex the fit does not pull to (see _fit_cage)
    if guard:
        everything = np.concatenate([bd.vertices for bd in bodies])
        pulled = np.zeros(len(everything), bool)
        pulled[owner_offset[targets.body] + targets.vertex] = True
        guarded = everything[~pulled]
    else:
        guarded = np.zeros((0, 3))
    probe, probe_moving = phases[0][0], phases[0][1]
    probe_normals = sample_probes[0]

    # the last measurement, the best iterate's and the cage's: the final
    # report's (of the best iterate) and the polish's first (from the best
    # iterate) are often of control points measured already, with the same
    # probes, and every round of a fit measures the cage first
    last, kept = [], []
    last_tree = []  # the samples of the last measurement and their k-d tree (the guarded vertices search it too)
    cage_measured = shared.setdefault("cage", []) if shared is not None else []

    def measure(P):
        for seen in (last, kept, cage_measured):
            if seen and seen[0] is probe and np.array_equal(seen[1], P):
                last[:] = seen
                return seen[2]
        out = _measure(P)
        last[:] = [probe, P.copy(), out]
        return out

    def keep_last():
        """The last measurement is the best iterate's: kept for the final report."""
        kept[:] = last

    def _measure(P):
        X = limit @ P
        N = ops.limit_normals(P, X)
        # the correspondences, beside the probes' depths where a side thread runs (seatkit.side)
        correspondences = beside(_correspondences, X, N, b, on_boundary)
        Y = X if probe is limit else probe @ P
        # depth > 0: probe inside a body. Only probes that can be nearer the
        # skin than the clearance are asked: the others take no part in the
        # step (and the query would put them at least that far out too)
        depth, foot, out = skin_depth_near(skins, Y, p["clearance"])
        # the floor is an obstacle too: nothing goes below y = 0
        below = -Y[:, 1] > np.maximum(depth, 0.0)
        depth = np.where(below, -Y[:, 1], depth)
        foot = np.where(below[:, None], Y * [1.0, 0.0, 1.0], foot)
        out = np.where(below[:, None], [0.0, 1.0, 0.0], out)
        if p["retreat"]:
            # a probe inside the body leaves it backwards, along the surface's
            # own normal (-n): the body rests on the front of a support, and
            # every probe of a sheet cut through a limb then agrees on the
            # way out (the skin's nearest side would split the sheet, half of
            # it pulled to each side of the limb). Where that way out is long
            # (the surface faces away from the body there), the skin's nearest
            # side is kept.
            # (shallow probes keep the skin's nearest side: it is as good there)
            inside = np.flatnonzero((depth > 0.5 * p["clearance"]) & ~below)
            if inside.size:
                # (the normals of these probes alone: each row's sum is the same)
                Yn = probe_normals[inside] @ N
                Yn /= np.maximum(row_norms(Yn)[:, None], 1e-300)
                back = -Yn
                # the way out, sampled along the ray at up to 2 depth + 2 cm
                # (one batched query), the exit between the last sample inside
                # and the first outside
                t = depth[inside, None] * _RETREAT_SCALE[None, :] + _RETREAT_EXTRA[None, :]
                ray = Y[inside, None, :] + t[:, :, None] * back[:, None, :]
                dd = _depths_to_exit(skins, ray)
                outside = dd <= 0.0
                exits = outside.any(axis=1)
                first = np.argmax(outside, axis=1)
                rows = np.arange(inside.size)
                prev_t = np.where(first > 0, t[rows, np.maximum(first - 1, 0)], 0.0)
                prev_d = np.where(first > 0, dd[rows, np.maximum(first - 1, 0)], depth[inside])
                d_out = dd[rows, first]
                t_exit = prev_t + (t[rows, first] - prev_t) * prev_d / np.maximum(prev_d - d_out, 1e-12)
                # backwards, but not against the skin's nearest way out (there
                # the surface faces away from the body: a side wall around a
                # shoulder), and not the long way through a limb
                agree = np.einsum("ij,ij->i", back, out[inside]) > -p["retreat_agreement"]
                short = agree & exits
                t = t_exit
                k = inside[short]
                foot[k] = Y[k] + t[short, None] * back[short]
                out[k] = back[short]
        tree, (closest, dist, _) = correspondences()
        last_tree[:] = [X, tree]
        mean = float(np.sum(w_base * dist) / w_sum)
        return X, N, closest, dist, mean, (foot, out, below), depth

    mu = p["point_to_point"]

    def solve_step(P, N, closest, w, pen, phase):
        P_m = P[cols]
        used = np.flatnonzero(w > 0)
        c = closest[used]
        # the samples used, sorted, and which one each target uses (np.unique's answer, without its sort)
        count = np.bincount(c, minlength=len(N))
        samples = np.flatnonzero(count)
        inverse = (np.cumsum(count > 0) - 1)[c]
        W = np.bincount(inverse, weights=w[used] / w_sum)
        WB = np.stack([np.bincount(inverse, weights=w[used] / w_sum * b[used, d]) for d in range(3)], axis=1)
        n_s = np.take(N, samples, axis=0)
        target = WB - W[:, None] * np.take(fixed_X, samples, axis=0)  # sum of w (b - fixed) per sample
        rhs_plane = np.einsum("sc,sc->s", n_s, target)
        idx, g, foot_a, gap_a, wp2 = pen
        goal = np.einsum("kc,kc->k", g, foot_a - probe_fixed[phase][idx]) + gap_a
        if dense_step:
            Ls = np.take(limit_rows, samples, axis=0)
            R = np.sqrt(W)[:, None] * Ls
            _, A = _gram_by_coordinate(n_s, R)
            # the point-to-point term, mu R^T R on each coordinate's diagonal block
            RtR = mu * (R.T @ R)
            for d in range(3):
                A[d * m : (d + 1) * m, d * m : (d + 1) * m] += RtR
            A += base
            rhs = np.concatenate([Ls.T @ (n_s[:, d] * rhs_plane + mu * target[:, d]) for d in range(3)])
            if idx.size:
                if probe_rows[phase] is None:
                    probe_rows[phase] = phases[phase][1].toarray()
                Q = np.sqrt(wp2)[:, None] * np.take(probe_rows[phase], idx, axis=0)
                QQ, QtQ = _gram_by_coordinate(g, Q)
                A += QtQ
                rhs += QQ.T @ (np.sqrt(wp2) * goal)
            rhs += base_rhs + (p["damping"] / n) * P_m.T.ravel()
            return np.linalg.solve(A, rhs)
        Ls = phases[0][1][samples]  # the limit samples' rows, of the moving control points
        R = sp.diags(np.sqrt(W)) @ Ls
        RR = sp.hstack([sp.diags(n_s[:, d]) @ R for d in range(3)]).tocsr()
        A = RR.T @ RR + sp.block_diag([mu * (R.T @ R)] * 3) + base
        rhs = np.concatenate([Ls.T @ (n_s[:, d] * rhs_plane + mu * target[:, d]) for d in range(3)])
        if idx.size:
            Q = sp.diags(np.sqrt(wp2)) @ phases[phase][1][idx]
            QQ = sp.hstack([sp.diags(g[:, d]) @ Q for d in range(3)]).tocsr()
            A = A + QQ.T @ QQ
            rhs = rhs + QQ.T @ (np.sqrt(wp2) * goal)
        rhs = rhs + base_rhs + (p["damping"] / n) * P_m.T.ravel()
        return spla.spsolve(A.tocsc(), rhs)

    def guarded_inside(X, N):
        """The guarded body vertices inside the furniture (the ray parity of the evaluation, on the fit's tessellation), their closest limit samples and distances to them."""
        held = guarded[inside_furniture(Surface(X, N, ops.faces, p["level"]), guarded)] if len(guarded) else guarded
        if not len(held):
            return held, np.zeros(0, np.int64), np.zeros(0)
        # (in the k-d tree the measurement of these samples made, when it was the last one)
        tree = last_tree[1] if last_tree and last_tree[0] is X else None
        c_hit, g_dist, _ = surface_distances(X, N, held, tree=tree)
        return held, c_hit, g_dist

    def deepest(depth, inside):
        """The depth an iterate is judged by: its deepest probe in a body or below the floor, and in a guarded fit its deepest guarded vertex inside the furniture."""
        return float(max(depth.max(), inside[2].max(initial=0.0), 0.0))

    P = p0.copy()
    X, N, closest, dist, mean, near, depth = measure(P)
    cage_measured[:] = last
    before = {"mean_distance": mean, "max_penetration": float(max(depth.max(), 0.0))}
    if start_from is not None:  # a refit: from an earlier fit's control points, still faired towards the cage's
        P = np.array(start_from, dtype=np.float64)
        X, N, closest, dist, mean, near, depth = measure(P)
    inside = guarded_inside(X, N)
    history = [mean]
    best = (P.copy(), mean, deepest(depth, inside))
    keep_last()
    stall = 0
    iterations = 0
    step_scale = []  # per iteration: the share of the solved step the trust region let through
    depth_history = []  # per iteration: the depth the iterate is judged by (its deepest probe in a body; in a guarded fit also its deepest guarded vertex inside the furniture), m
    for phase, (probe, probe_moving, n_iter) in enumerate(phases):
        probe_normals = sample_probes[phase]
        if phase == 1:
            # polish: from the best iterate, with the denser probes
            P = best[0].copy()
            X, N, closest, dist, mean, near, depth = measure(P)
            inside = guarded_inside(X, N)
            if deepest(depth, inside) <= p["max_penetration"]:
                break
            best = (P.copy(), mean, deepest(depth, inside))
            keep_last()
            history.append(mean)
            stall = 0
        since_deeper = 0
        for it in range(n_iter + p["extra_iterations"]):
            # past the phase's budget only while the penetration limit is not
            # met and the depth still falls (a large body can need 3-4 times
            # the iterations: p95-male armrest-sitting stopped 19.6 mm deep)
            if it >= n_iter and (best[2] <= p["max_penetration"] or since_deeper >= _DEPTH_PATIENCE):
                break
            iterations += 1
            checkpoint()  # seatkit serve stops here when a newer request has arrived
            # a support holds skin that faces it: a correspondence whose skin
            # normal does not oppose the surface normal (the front of a shin
            # matched to a seat below the knee) would wrap the surface around
            # the limb, so it is left out
            N_c = np.take(N, closest, axis=0)
            facing = np.einsum("kc,kc->k", target_n, N_c) < -p["min_facing"]
            use = (dist <= p["max_distance"]) & facing
            w = w_base * use
            # a supported skin vertex behind the surface (a crease the
            # surface bridges, as between the thighs: no probe is inside the
            # body, yet the skin at the bottom of the crease is inside the
            # furniture; a sole on the floor under a surface a few mm above
            # it, its target held at y = 0) is pulled out as firmly as a
            # probe inside the body
            X_c = np.take(X, closest, axis=0)
            behind = use & (np.einsum("kc,kc->k", N_c, targets.points - X_c) < 0)
            w = np.where(behind, np.maximum(w, w_pen), w)
            foot, out, below = near
            # probes under the floor are lifted to it (no clearance: the
            # furniture stands on the floor); probes in the body or closer than
            # the clearance are pushed out along their way out (see measure)
            gap = np.where(below, 0.0, p["clearance"])
            idx = np.flatnonzero(depth > -gap)
            # skin resting on the floor (soles): the floor holds it; pushing the
            # surface out along its downward normal would push it underground
            on_floor = ~below[idx] & (foot[idx, 1] < p["clearance"]) & (out[idx, 1] < -0.5)
            idx = idx[~on_floor]
            boost = 1.0 + np.minimum(depth[idx].clip(0) / p["clearance"], 4.0)
            pen = (idx, out[idx], foot[idx], gap[idx], w_pen / w_sum * boost)
            held, c_hit, g_dist = inside
            if len(held):
                # guarded body vertices inside the furniture: their closest
                # limit sample is pushed back past them by the clearance,
                # along minus its normal
                g_boost = 1.0 + np.minimum(g_dist / p["clearance"], 4.0)
                pen = (
                    np.concatenate([idx, c_hit]),
                    np.concatenate([out[idx], -N[c_hit]]),
                    np.concatenate([foot[idx], held]),
                    np.concatenate([gap[idx], np.full(len(held), p["clearance"])]),
                    np.concatenate([pen[4], w_pen / w_sum * g_boost]),
                )
            try:
                solution = solve_step(P, N, closest, w, pen, phase)
            except (RuntimeError, np.linalg.LinAlgError) as exc:  # singular factorisation
                msg = f"catmull-clark-fit: the linear solve failed at iteration {iterations}: {exc}"
                raise SolverError(msg) from exc
            if not np.all(np.isfinite(solution)):
                msg = f"catmull-clark-fit: the fit diverged (non-finite control points at iteration {iterations})"
                raise SolverError(msg)
            P_prev = P
            P = P.copy()
            P[cols] = solution.reshape(3, m).T
            # a trust region: the correspondences, normals and the probes'
            # ways out are only valid near the current surface, so the step
            # is shortened until no control point moves farther than max_step
            # (or than the mean distance, while the surface is still far away:
            # a flat patch rising from the floor)
            longest = float(np.linalg.norm(P - P_prev, axis=1).max())
            reach = max(p["max_step"], history[-1])
            if _observe is not None:
                _observe(
                    P=P_prev,
                    solved=P,
                    cols=cols,
                    reach=reach,
                    limit=limit,
                    X=X,
                    N=N,
                    N_probe=probe_normals @ N,
                    depth=depth,
                    depth_samples=depth if probe is limit else None,
                    w=w,
                    w_base=w_base,
                    w_sum=w_sum,
                    dist=dist,
                    pen=pen,
                    closest=closest,
                    point_to_point=mu,
                    probe=probe,
                    fairness_diag=3.0 * fair.diagonal(),
                    solve=lambda w_, pen_, P_=P_prev, N_=N, c_=closest, ph_=phase: solve_step(P_, N_, c_, w_, pen_, ph_),
                    measure=_measure,
                )
            if longest > reach:
                P = P_prev + (reach / longest) * (P - P_prev)
            step_scale.append(min(1.0, reach / longest) if longest > 0.0 else 1.0)
            X, N, closest, dist, mean, near, depth = measure(P)
            inside = guarded_inside(X, N)
            history.append(mean)
            max_depth = deepest(depth, inside)
            depth_history.append(max_depth)
            ok = max_depth <= p["max_penetration"]
            best_ok = best[2] <= p["max_penetration"]
            # the closest iterate within the penetration limit; until one is, the shallowest
            deeper_gain = not best_ok and max_depth < best[2] - 1e-4
            since_deeper = 0 if deeper_gain or ok else since_deeper + 1
            if (ok and (not best_ok or mean < best[1])) or (not best_ok and max_depth < best[2]):
                best = (P.copy(), mean, max_depth)
                keep_last()
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
            f"catmull-clark-fit: the surface stays {depth_best * 1000:.1f} mm inside the body "
            f"(max_penetration {p['max_penetration'] * 1000:.1f} mm) after {iterations} iterations"
        )
        raise SolverError(msg)
    final_depth = _final_depths(replace(mesh, vertices=P_best), bodies, p["level"]) if p["surface_limit"] > 0 else None
    X, N, closest, dist, mean, near, depth = measure(P_best)
    meta = dict(mesh.meta)
    meta["catmull-clark-fit"] = {
        "before": before,
        "after": {"mean_distance": mean, "max_penetration": float(max(depth.max(), 0.0))},
        "final_depth": final_depth,
        "supported_vertices": int(k_sup),
        "supported_segments": [list(s) for s in targets.segments],
        "iterations": int(iterations),
        "history": history,
        "step_scale": step_scale,
        "depth_history": depth_history,
        "seconds": time.perf_counter() - start,
        "params": p,
    }
    return replace(mesh, vertices=P_best, meta=meta)


def _final_depths(mesh: ControlMesh, bodies: Sequence[Body], level: int) -> dict[str, float]:
    """How deep the cage's limit surface reaches into the bodies, and they into it, m.

    The two figures the evaluation reports (``max_penetration_m`` and
    ``max_body_depth_m``, :mod:`seatkit.evaluate`), the larger over the
    tessellations of ``level`` (the fit's, 3 by default as the exported
    surface's) and level 4: a coarser tessellation's chords can read
    deeper than the limit surface.
    """
    from seatkit.subdivision import Cage, build_operators

    cage = Cage.from_control_mesh(mesh)
    surfaces = []
    for lv in sorted({level, 4}):
        ops = build_operators(cage, lv)
        X = ops.limit_points(mesh.vertices)
        # positions alone: both depths are distances, the normals would go unread
        # (and level 4's tangent operators unmade)
        surfaces.append(Surface(X, np.zeros_like(X), ops.faces, lv))
    # the surface in the body: the probes of surface_depth_in_body (every
    # tessellation vertex and quad centre) of both tessellations in one
    # query per body; a coarser level's vertices are the first limit points
    # of the finer one (a vertex's limit position does not change with
    # refinement), so only its quad centres are added
    finest = surfaces[-1]
    # (np.take gathers rows several times faster than indexing does)
    probes = [finest.vertices, np.take(finest.vertices, finest.faces, axis=0).mean(axis=1)]
    probes += [np.take(s.vertices, s.faces, axis=0).mean(axis=1) for s in surfaces[:-1]]
    points = np.concatenate(probes)
    # a body vertex inside the furniture, at each level (a coarser
    # tessellation's chords can read deeper than the finer one's), beside
    # the surface's depth in the bodies where a side thread runs
    in_surface = [beside(body_depth_in_surface, s, b) for s in surfaces for b in bodies]
    surface_in_body = max(SkinDistance.of(b.vertices, b.faces).max_depth(points) for b in bodies)
    body_in_surface = max(depth() for depth in in_surface)
    return {"surface_in_body": float(surface_in_body), "body_in_surface": float(body_in_surface)}


class CatmullClarkFitRefiner:
    """The ``catmull-clark-fit`` refiner: Sit & Relax's limit-surface fit."""

    name = "catmull-clark-fit"
    description = "Catmull-Clark limit surface fitted to the supported body regions (Sit & Relax)"
    options = CCFIT_OPTIONS

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
        distance to the closest limit sample), ``avg_distance`` (m, the
        paper's Table 1 figure as :mod:`seatkit.evaluate` computes it: mean
        distance from the supported body vertices, those loaded in the
        importance map on the segments the cage supports, to the closest
        point of the tessellated limit surface), ``max_penetration`` (m, how
        deep the limit surface reaches into any body, measured from the
        closed skin: :func:`seatkit.geometry.surface.surface_depth_in_body`),
        ``max_body_depth`` (m, how deep any body vertex lies inside the
        furniture the surface closes with the floor:
        :func:`seatkit.geometry.surface.body_depth_in_surface`),
        ``supported_vertices``.
    """
    from seatkit.subdivision import Cage, build_operators

    targets = supported_targets(mesh, bodies, pressures, threshold=threshold)
    ops = build_operators(Cage.from_control_mesh(mesh), level)
    X = ops.limit_points(mesh.vertices)
    N = ops.limit_normals(mesh.vertices)
    boundary = _boundary_samples(ops)
    _, dist, signed = surface_distances(X, N, targets.points, boundary=boundary)

    surface = Surface(X, N, ops.faces, level)

    query = SurfaceQuery(surface)
    gaps = []
    for body, pressure, segs in zip(bodies, pressures, targets.segments):
        mask = supported_vertices(pressure, body, segs)
        if mask.any():
            gaps.append(query.query(body.vertices[mask])[0])
    return {
        "avg_distance": float(np.concatenate(gaps).mean()) if gaps else float("nan"),
        "mean_distance": float(np.sum(targets.weights * np.abs(signed)) / targets.weights.sum()),
        "mean_euclidean_distance": float(dist.mean()),
        # how deep the surface reaches into any body (measured from the closed skin)
        "max_penetration": max(surface_depth_in_body(surface, b) for b in bodies),
        # how deep any body vertex lies inside the furniture (surface closed by the floor)
        "max_body_depth": max(body_depth_in_surface(surface, b, query) for b in bodies),
        "supported_vertices": int(len(targets.points)),
    }
