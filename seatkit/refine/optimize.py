"""The paper's mesh optimisation (Section 5.3, Appendix B).

Minimises ::

    E = lambda_S (S_L + S_A) + lambda_D (D_V + D_P)

over the control points of a quad cage:

- ``S_L``: importance-weighted Laplacian, ``lambda_laplacian * sum_i
  || v_i - sum_j w_j v_j / sum_j w_j ||^2`` over the 1-ring ``j`` of ``i``;
- ``S_A``: per face, ``lambda_regular * (sum_k alpha_k - 2 pi)^2 +
  lambda_max_angle * sum_k (alpha_k - pi)^2`` (the paper's regular-face and
  maximal-angle terms, face weights ``w^1 = w^2 = 1``);
- ``D_V``: ``lambda_vertex * sum_i w_i || v_i - v~_i ||^2``, the distance to
  the template's positions;
- ``D_P``: ``lambda_plane * sum_faces sum_{i in F} w_i <v_i - c_F, n_F>^2``,
  the distance of each face's corners to the supporting plane the template
  fitted for it (faces with NaN planes are skipped);

with the hard constraints of the paper: ground vertices stay on the edges of
the ground rectangle (they slide along their edge, rectangle corners stay
put; fixed non-ground vertices do not move) and every edge is at least
``min_edge_length`` long; and one of ours: no corner angle ends below
``min(its angle in the template, min_corner_angle_deg)``.

Lengths are measured in units of the cage's mean edge length inside the
solver, so the weights are dimensionless and independent of the cage's size.
The ground constraints are met exactly by construction: a free vertex has
three unknowns, a sliding vertex one, its position ``t`` along its rectangle
side (y = 0; bounds keep it on the side and, next to a corner vertex, at least
the minimal edge length from it), a corner or fixed vertex none. The energy's
analytic gradient reaches the unknowns by the chain rule through this affine
map. The edge-length and corner-angle inequalities are the only constraints
left; they go into the objective as augmented-Lagrangian terms aimed at
``l (1 + 1e-4)`` and ``theta (1 + 1e-4)`` (so that what the penalty leaves
unmet still meets ``l`` or ``theta``). Edges: linear in the signed length for
edges along a rectangle side (so sliding vertices keep their order whatever
the step), ``l/2 (1 - l^2 / |e|^2)`` (unbounded as the edge shrinks) for the
others. Corners: ``(alpha - theta) l_k``, the angle times the geometric mean
of the corner's two edges in the template (a length, so one penalty weight
suits both); the angles and their chain rule are shared with ``S_A``. The
bound-constrained problem is solved by scipy's L-BFGS-B, with multiplier
updates until every constraint is met (usually 5-7 rounds, all but the first
a few dozen iterations). The result is then checked: an edge shorter than
``min_edge_length`` by more than a relative 1e-6 (of its square), a corner
angle below its floor by more than a relative 1e-6, or two ground vertices
that passed each other, is a ``SolverError``.

Why the corner-angle floor: the paper's maximal-angle term ``(alpha - pi)^2``
pushes a 4 deg corner open only twice as hard as a right angle (its slope is
``2 (alpha - pi)``), so it barely sees slivers. The chair's border has one at
each back corner of the ground rectangle: a face with three ground vertices
(the rectangle corner and one sliding vertex on each side) and one at the top
of the backrest, about 1.1 m tall on a 5-7 cm base. On crossed-legs-ankles
the Laplacian and regular-face terms slide the ground vertex next to the
corner in to ``min_edge_length``, and the sliver's apex angle closed from
4.24 deg (the template's) to 3.98 deg: the cage's minimal angle got worse. The floor keeps it at 4.24 deg; where no floor binds at the
end (the other eight library poses, the benches) the results move by at most
0.1 mm.

Every step costs O(v) (sparse products, vectorised per-face terms, limited
memory quasi-Newton), and the number of iterations (200-300) does not grow
with the cage. On a chair-sized cage an evaluation of the energy, its
gradient and the penalties (about 300 a run) is a few dozen numpy calls on
arrays of a few hundred entries, so each call's fixed overhead, not the
arithmetic, is the cost: the sparse products are summed with
``np.bincount`` (:class:`_RowSums`: scipy's sums to the bit, without its
dispatch), rows are gathered with ``take`` (fancy indexing of an (n, 3)
array is several times slower), every corner's edges come from one gather
and the angles' parts are shared with their gradient. That is about 0.1 s of
CPU for the 96-point chair cage, one BLAS thread (docs/performance.md,
``benchmarks/bench_optimize.py``). The SLSQP solver
used before (dense QP subproblems, O(v^3)) took 0.7-0.9 s and 4 s (3-person
bench) to reach the same energies.

Departures from the paper, and why:

- The vertex weights ``w`` are the template's ``vertex_weights`` scaled to a
  maximum of 1. In the Laplacian's weighted average they are floored at
  ``laplacian_weight_floor`` so that a vertex whose neighbours all have zero
  importance still has an average.
- Face weights of the angle terms are 1 (the paper leaves them unspecified).
- The corner-angle floor (above) is not in the paper.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Sequence

import numpy as np
import scipy.optimize
import scipy.sparse as sp

from seatkit.errors import SolverError
from seatkit.model import Body, ControlMesh, PressureField
from seatkit.options import Option, defaults
from seatkit.params import refiner_params
from seatkit.refine.quality import cage_quality, mesh_edges

__all__ = ["OPTIMIZE_DEFAULTS", "OPTIMIZE_OPTIONS", "CageEnergy", "optimize_cage", "OptimizeRefiner"]

#: Options of ``optimize`` (weights dimensionless, lengths in m): its parameters' one declaration.
OPTIMIZE_OPTIONS: dict[str, Option] = {
    "lambda_smooth": Option("number", "lambda_S, weight of the mesh term", 1.0, "1", 0.0, 1e6),
    "lambda_data": Option("number", "lambda_D, weight of the data term", 10.0, "1", 0.0, 1e6),
    "lambda_laplacian": Option("number", "lambda_S^l, the Laplacian term", 1.0, "1", 0.0, 1e6),
    "lambda_regular": Option("number", "lambda_S^A1, (sum alpha - 2 pi)^2", 1.0, "1", 0.0, 1e6),
    "lambda_max_angle": Option("number", "lambda_S^A2, sum (alpha - pi)^2", 1.0, "1", 0.0, 1e6),
    "lambda_vertex": Option("number", "lambda_D^V, the vertex term", 1.0, "1", 0.0, 1e6),
    "lambda_plane": Option("number", "lambda_D^P, the plane term", 1.0, "1", 0.0, 1e6),
    "laplacian_weight_floor": Option("number", "smallest neighbour weight in the Laplacian average", 0.1, "1", 0.0, 1.0),
    "min_edge_length": Option("number", "shortest edge with a moving end (hard constraint)", 0.02, "m", 0.0, 1.0),
    "min_corner_angle_deg": Option("number", "no corner below min(its template angle, this) (hard constraint); 0: off", 15.0, "deg", 0.0, 89.0),
    "slide_border": Option("bool", "ground vertices slide along their rectangle edge", True),
    "max_iterations": Option("count", "L-BFGS-B iterations per run (one run per penalty round)", 300, "", 1, 100000),
    "tolerance": Option("number", "L-BFGS-B's ftol: relative energy decrease that ends a run", 1e-9, "1", 0.0, 1.0),
}

#: Default parameters of ``optimize`` (from :data:`OPTIMIZE_OPTIONS`).
OPTIMIZE_DEFAULTS: dict[str, Any] = defaults(OPTIMIZE_OPTIONS)

#: Relative tolerance when checking that a vertex lies on the ground rectangle.
_RECT_TOL = 1e-6
#: Previous and next corner of each quad corner; cyclic coordinate shifts for
#: the cross product ``a x b = a[C1] b[C2] - a[C2] b[C1]``.
_PREV = np.array([3, 0, 1, 2])
_NEXT = np.array([1, 2, 3, 0])
_C1 = np.array([1, 2, 0])
_C2 = np.array([2, 0, 1])
#: ``np.sum`` without its Python wrapper (the same reduction): paid a few
#: times per energy evaluation, hundreds of evaluations per run.
_sum = np.add.reduce


def _scatter_matrix(index: np.ndarray, n: int) -> sp.csr_matrix:
    """(n, len(index)) matrix summing rows of a per-corner array into vertices."""
    m = index.size
    return sp.csr_matrix((np.ones(m), (index, np.arange(m))), shape=(n, m))


class _RowSums:
    """``matrix @ x`` for a fixed sparse matrix, added up with ``np.bincount``.

    Each row's products are the ones scipy's CSR kernel forms, added in the
    same order starting from zero, so the result is scipy's to the bit (a CSC
    matrix, such as a transpose, is turned into CSR first: its rows then list
    their entries in the order the CSC kernel adds them). It skips
    scipy.sparse's checks and dispatch, which on a cage of a hundred vertices
    cost as much as the product itself, seven products per energy evaluation.

    Parameters
    ----------
    matrix : sparse matrix
        (n, m); ``x`` is (m,) or (m, 3), the product (n,) or (n, 3).
    """

    def __init__(self, matrix: sp.spmatrix):
        csr = sp.csr_matrix(matrix)
        n = csr.shape[0]
        self.shape = csr.shape
        rows = np.repeat(np.arange(n), np.diff(csr.indptr))
        cols = csr.indices.astype(np.intp)
        data = csr.data.astype(np.float64)
        #: every entry 1: the products are the gathered values themselves
        self.ones = bool(np.all(data == 1.0))
        # for (m,) vectors the entries as stored; for (m, 3) arrays, flattened,
        # each entry for the three coordinates in turn (every output still
        # gets its entries in stored order)
        rows3, cols3 = ((3 * a[:, None] + np.arange(3)).ravel() for a in (rows, cols))
        self.flat = {1: (rows, cols, data), 3: (rows3, cols3, np.repeat(data, 3))}

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        width = 1 if x.ndim == 1 else x.shape[1]
        rows, cols, data = self.flat[width]
        products = x.reshape(-1).take(cols)
        if not self.ones:
            products = data * products
        out = np.bincount(rows, weights=products, minlength=self.shape[0] * width)
        return out if x.ndim == 1 else out.reshape(-1, width)


def _around(faces: np.ndarray) -> np.ndarray:
    """(3, f, 4) each corner of the quads ``faces``, the corner before it and the corner after it."""
    return np.stack([faces, faces[:, _PREV], faces[:, _NEXT]]).astype(np.intp)


def _corner_angles(x: np.ndarray, faces: np.ndarray, around: np.ndarray | None = None) -> tuple[np.ndarray, tuple]:
    """Interior angle of every corner of the quads ``faces`` at ``x``.

    Returns ``alpha`` (f, 4) = atan2(|a x b|, a . b), ``a`` and ``b`` the edges
    to the previous and the next corner, and the parts the gradient needs
    (:func:`_angle_gradient`): ``(a, b)`` (2, f, 4, 3), ``|a x b|``, ``a . b``
    and ``(|a|^2, |b|^2)`` (2, f, 4). ``around`` is :func:`_around` of
    ``faces`` (made here when not given).
    """
    if around is None:
        around = _around(faces)
    # take: the same rows as x[around], at a fraction of fancy indexing's cost
    corners = x.take(around, axis=0)  # (3, f, 4, 3)
    ab = corners[1:] - corners[0]
    first, second = ab.take(_C1, axis=-1), ab.take(_C2, axis=-1)
    cross = first[0] * second[1] - second[0] * first[1]
    cross *= cross
    # the three squares added in order (a dot product's SIMD path would round differently)
    sin_part = np.sqrt(cross[..., 0] + cross[..., 1] + cross[..., 2])
    cos_part = np.einsum("fkc,fkc->fk", ab[0], ab[1])
    squares = np.einsum("sfkc,sfkc->sfk", ab, ab)
    return np.arctan2(sin_part, cos_part), (ab, sin_part, cos_part, squares)


def _angle_gradient(parts: tuple, d_alpha: np.ndarray) -> np.ndarray:
    """Gradient of ``sum d_alpha * alpha`` w.r.t. each face's corners.

    Parameters
    ----------
    parts : tuple
        From :func:`_corner_angles`.
    d_alpha : (f, 4) float64
        Derivative of the function with respect to each corner's angle.

    Returns
    -------
    (f, 4, 3) float64
        Row ``[j, k]`` is the derivative w.r.t. the position of corner ``k``
        of face ``j`` (sum rows into vertices with a scatter matrix).
    """
    ab, sin_part, cos_part, squares = parts
    # d alpha / d a = -b_perp / |a x b|, b_perp = b minus its component along a
    # (and the same with a and b swapped): both at once, (b_perp, a_perp)
    # (dividing by -|a x b| is negating the quotient, exactly: the small array is negated)
    minus_safe = -np.maximum(sin_part, 1e-300)[..., None]
    perp = ab[::-1] - (cos_part / np.maximum(squares, 1e-300))[..., None] * ab
    # w.r.t. the previous corner (row 0) and the next corner (row 1)
    g = perp / minus_safe * d_alpha[..., None]
    # corner k gets -(g_a + g_b) from its own angle, g_a from the angle
    # of corner k+1 (k is its previous) and g_b from corner k-1
    return g[0].take(_NEXT, axis=1) - (g[0] + g[1]) + g[1].take(_PREV, axis=1)


@dataclass(frozen=True)
class CageEnergy:
    """The energy ``E`` of the paper on a fixed topology, with its gradient.

    All positions are in normalised units (see :func:`optimize_cage`).

    Attributes
    ----------
    faces : (f, 4) int64
    rest : (v, 3) float64
        The template's positions ``v~``.
    weights : (v,) float64
        Vertex importance in [0, 1].
    laplacian : (v, v) csr_matrix
        ``I - D^-1 A W``: row ``i`` gives ``v_i`` minus its weighted average.
    plane_faces : (g,) int64
        Faces with a supporting plane.
    plane_points, plane_normals : (g, 3) float64
    coeffs : dict of str to float
        The products of global and term weights.
    corner_scatter : (v, 4 f) csr_matrix
        Sums per-corner rows (face-major) into their vertices.
    plane_scatter : (v, 4 g) csr_matrix
        The same for the corners of the faces with a plane.
    """

    faces: np.ndarray
    rest: np.ndarray
    weights: np.ndarray
    laplacian: sp.csr_matrix
    plane_faces: np.ndarray
    plane_points: np.ndarray
    plane_normals: np.ndarray
    coeffs: dict
    corner_scatter: sp.csr_matrix
    plane_scatter: sp.csr_matrix
    #: What every evaluation reuses: the sparse products as :class:`_RowSums`
    #: (``laplacian``, its transpose, the scatters), the corners around each
    #: corner, the corners of the faces with a plane and their weights.
    _fixed: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        plane_corners = self.faces[self.plane_faces]
        fixed = {
            "laplacian": _RowSums(self.laplacian),
            "laplacian_t": _RowSums(self.laplacian.T),
            "corner_scatter": _RowSums(self.corner_scatter),
            "plane_scatter": _RowSums(self.plane_scatter),
            "around": _around(self.faces),
            "plane_corners": plane_corners,
            "plane_weights": self.weights[plane_corners],
            "vertex_weights": self.weights[:, None],
        }
        object.__setattr__(self, "_fixed", fixed)

    @classmethod
    def build(
        cls,
        vertices: np.ndarray,
        faces: np.ndarray,
        weights: np.ndarray,
        plane_points: np.ndarray,
        plane_normals: np.ndarray,
        params: Mapping[str, Any],
    ) -> "CageEnergy":
        """Precompute the topology-dependent parts.

        Parameters
        ----------
        vertices : (v, 3) float64
            Rest (template) positions.
        faces : (f, 4) int64
        weights : (v,) float64
            Importance in [0, 1].
        plane_points, plane_normals : (f, 3) float64
            NaN rows for faces without a plane.
        params : mapping
            Merged ``OPTIMIZE_DEFAULTS``.
        """
        n = len(vertices)
        edges = mesh_edges(faces)
        # symmetric 1-ring adjacency
        rows = np.concatenate([edges[:, 0], edges[:, 1]])
        cols = np.concatenate([edges[:, 1], edges[:, 0]])
        lap_w = np.maximum(weights, params["laplacian_weight_floor"])
        # A W: neighbour weights; divide each row by its sum -> weighted average
        aw = sp.csr_matrix((lap_w[cols], (rows, cols)), shape=(n, n))
        row_sum = np.asarray(aw.sum(axis=1)).ravel()
        average = sp.diags(1.0 / np.maximum(row_sum, 1e-300)) @ aw
        laplacian = (sp.identity(n, format="csr") - average).tocsr()

        has_plane = np.all(np.isfinite(plane_points), axis=1) & np.all(np.isfinite(plane_normals), axis=1)
        plane_faces = np.flatnonzero(has_plane)
        normals = plane_normals[plane_faces]
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        p = params
        coeffs = {
            "laplacian": p["lambda_smooth"] * p["lambda_laplacian"],
            "regular": p["lambda_smooth"] * p["lambda_regular"],
            "max_angle": p["lambda_smooth"] * p["lambda_max_angle"],
            "vertex": p["lambda_data"] * p["lambda_vertex"],
            "plane": p["lambda_data"] * p["lambda_plane"],
        }
        return cls(
            faces=np.asarray(faces, dtype=np.int64),
            rest=np.array(vertices, dtype=np.float64),
            weights=np.asarray(weights, dtype=np.float64),
            laplacian=laplacian,
            plane_faces=plane_faces,
            plane_points=plane_points[plane_faces],
            plane_normals=normals,
            coeffs=coeffs,
            corner_scatter=_scatter_matrix(np.asarray(faces, dtype=np.int64).ravel(), n),
            plane_scatter=_scatter_matrix(np.asarray(faces, dtype=np.int64)[plane_faces].ravel(), n),
        )

    def terms(self, x: np.ndarray) -> dict[str, float]:
        """Each weighted term's value at ``x`` (v, 3)."""
        return self._evaluate(x, want_grad=False)[2]

    def value_and_grad(self, x: np.ndarray, angle_penalty=None) -> tuple[float, np.ndarray]:
        """Energy and gradient at ``x``.

        Parameters
        ----------
        x : (v, 3) float64
        angle_penalty : callable, optional
            ``alpha (f, 4) -> (value, d value / d alpha (f, 4))``, a function of
            the corner angles added to the energy (the corner-angle
            constraints' penalty; it shares the angles and their chain rule).

        Returns
        -------
        energy : float
        grad : (v, 3) float64
        """
        energy, grad, _ = self._evaluate(x, want_grad=True, angle_penalty=angle_penalty)
        return energy, grad

    def _evaluate(self, x: np.ndarray, *, want_grad: bool, angle_penalty=None):
        c = self.coeffs
        fixed = self._fixed
        grad = None
        terms: dict[str, float] = {}

        # S_L: squared distance of each vertex to its weighted 1-ring average
        residual = fixed["laplacian"] @ x
        terms["laplacian"] = c["laplacian"] * float(_sum(residual**2, axis=None))
        if want_grad:
            # the first term of the gradient (adding it to zeros would change no sum)
            grad = 2.0 * c["laplacian"] * (fixed["laplacian_t"] @ residual)

        # S_A: corner angles alpha = angle(a, b), a = prev - v, b = next - v
        alpha, parts = _corner_angles(x, self.faces, fixed["around"])
        sum_err = _sum(alpha, axis=1) - 2.0 * np.pi
        terms["regular"] = c["regular"] * float(_sum(sum_err**2, axis=None))
        off_flat = alpha - np.pi
        terms["max_angle"] = c["max_angle"] * float(_sum(off_flat**2, axis=None))
        extra = 0.0
        if want_grad:
            # dE/dalpha per corner
            d_alpha = 2.0 * c["regular"] * sum_err[:, None] + 2.0 * c["max_angle"] * off_flat
            if angle_penalty is not None:
                extra, d_extra = angle_penalty(alpha)
                d_alpha = d_alpha + d_extra
            grad += fixed["corner_scatter"] @ _angle_gradient(parts, d_alpha).reshape(-1, 3)

        # D_V: weighted squared distance to the template positions
        delta = x - self.rest
        w = fixed["vertex_weights"]
        terms["vertex"] = c["vertex"] * float(_sum(w * delta**2, axis=None))
        if want_grad:
            grad += 2.0 * c["vertex"] * w * delta

        # D_P: weighted squared distance of each face's corners to its plane
        if self.plane_faces.size:
            idx = fixed["plane_corners"]  # (g, 4)
            dist = np.einsum("gkc,gc->gk", x.take(idx, axis=0) - self.plane_points[:, None, :], self.plane_normals)
            w = fixed["plane_weights"]
            terms["plane"] = c["plane"] * float(_sum(w * dist**2, axis=None))
            if want_grad:
                g = 2.0 * c["plane"] * (w * dist)[..., None] * self.plane_normals[:, None, :]
                grad += fixed["plane_scatter"] @ g.reshape(-1, 3)
        else:
            terms["plane"] = 0.0

        energy = float(sum(terms.values())) + extra
        return energy, grad, terms


@dataclass(frozen=True)
class _Border:
    """Affine map from the reduced unknowns ``z`` to all coordinates ``x``.

    ``x.ravel() = base + basis @ z``; free vertices contribute three columns,
    vertices sliding along a rectangle edge one (the edge direction).
    """

    base: np.ndarray
    basis: sp.csr_matrix
    bounds: list
    moving: np.ndarray  # (v,) bool: vertex depends on z
    sliding: np.ndarray  # (v,) bool
    rectangle: dict


def _ground_rectangle(points_xz: np.ndarray, tol: float):
    """Find the rectangle the ground vertices lie on.

    Returns (origin (2,), axes (2, 2) rows u and w, lo (2,), hi (2,)) in the
    rectangle frame ``p = origin + u * axes[0] + w * axes[1]``.
    """

    def candidates():
        yield np.eye(2)
        if len(points_xz) >= 3:  # only when the axis-aligned one does not fit
            import trimesh

            transform, _ = trimesh.bounds.oriented_bounds_2D(points_xz)
            yield transform[:2, :2]

    for axes in candidates():
        local = points_xz @ axes.T
        lo, hi = local.min(axis=0), local.max(axis=0)
        on_side = np.abs(local - lo) <= tol
        on_side_hi = np.abs(local - hi) <= tol
        if np.all(on_side.any(axis=1) | on_side_hi.any(axis=1)):
            return np.zeros(2), axes, lo, hi
    return None


def _build_border(
    x: np.ndarray, ground: np.ndarray, fixed: np.ndarray, *, slide: bool, scale: float, gap: float = 0.0
) -> _Border:
    """Reduced parametrisation meeting the ground constraints exactly.

    A sliding vertex's bounds stop ``gap`` short of an end of its side where a
    corner vertex stands (it could never come closer than the minimal edge
    length to it, and a bound on the corner would let the solver put both at
    the same point).
    """
    n = len(x)
    tol = _RECT_TOL
    frozen = fixed & ~ground
    sliding = np.zeros(n, bool)
    base = x.copy()
    rectangle: dict = {}
    slide_dirs = np.zeros((n, 3))
    slide_param = np.zeros(n)
    bounds_slide = np.zeros((n, 2))
    if ground.any():
        gi = np.flatnonzero(ground)
        height = np.abs(x[gi, 1]).max()
        if height > tol:
            worst = gi[np.argmax(np.abs(x[gi, 1]))]
            msg = (
                f"optimize: ground vertex {worst} is at y = {x[worst, 1] * scale:.6g} m; "
                f"ground vertices must lie on y = 0"
            )
            raise SolverError(msg)
        found = _ground_rectangle(x[gi][:, [0, 2]], tol)
        if found is None:
            msg = "optimize: the ground vertices do not lie on the edges of a rectangle; cannot keep them on it"
            raise SolverError(msg)
        origin, axes, lo, hi = found
        local = x[gi][:, [0, 2]] @ axes.T
        rectangle = {"axes": axes, "lo": lo * scale, "hi": hi * scale}
        at_lo = np.abs(local - lo) <= tol
        at_hi = np.abs(local - hi) <= tol
        on_u_side = at_lo[:, 0] | at_hi[:, 0]  # u fixed, slides along w
        on_w_side = at_lo[:, 1] | at_hi[:, 1]  # w fixed, slides along u
        corner = on_u_side & on_w_side
        # snap every ground vertex exactly onto its side, y = 0
        snapped = local.copy()
        snapped[:, 0] = np.where(at_lo[:, 0], lo[0], np.where(at_hi[:, 0], hi[0], local[:, 0]))
        snapped[:, 1] = np.where(at_lo[:, 1], lo[1], np.where(at_hi[:, 1], hi[1], local[:, 1]))
        world = snapped @ axes
        base[gi, 0], base[gi, 1], base[gi, 2] = world[:, 0], 0.0, world[:, 1]
        if slide:
            slides = ~corner
            # along w for u-sides, along u for w-sides
            along = np.where(on_u_side[:, None], axes[1][None, :], axes[0][None, :])
            t = np.where(on_u_side, snapped[:, 1], snapped[:, 0])
            t_lo = np.where(on_u_side, lo[1], lo[0])
            t_hi = np.where(on_u_side, hi[1], hi[0])
            # the side's ends (local coordinates) and whether a corner vertex stands there
            fixed_coord = np.where(on_u_side, snapped[:, 0], snapped[:, 1])
            end_lo = np.where(
                on_u_side[:, None], np.column_stack([fixed_coord, t_lo]), np.column_stack([t_lo, fixed_coord])
            )
            end_hi = np.where(
                on_u_side[:, None], np.column_stack([fixed_coord, t_hi]), np.column_stack([t_hi, fixed_coord])
            )
            corner_pts = snapped[corner]

            def has_corner(ends):
                return (np.abs(ends[:, None, :] - corner_pts[None, :, :]) <= tol).all(axis=-1).any(axis=1)

            t_lo = t_lo + gap * has_corner(end_lo)
            t_hi = t_hi - gap * has_corner(end_hi)
            # a side exactly (count - 1) * gap long: meet in the middle
            crossed = t_lo > t_hi
            t_lo[crossed] = t_hi[crossed] = 0.5 * (t_lo[crossed] + t_hi[crossed])
            sl = gi[slides]
            sliding[sl] = True
            slide_dirs[sl] = np.column_stack([along[slides, 0], np.zeros(slides.sum()), along[slides, 1]])
            slide_param[sl] = t[slides]
            bounds_slide[sl] = np.column_stack([t_lo[slides], t_hi[slides]])
            # base of a sliding vertex: its position with the slide parameter at 0
            base[sl] -= slide_param[sl, None] * slide_dirs[sl]
        rectangle["corners_fixed"] = int(corner.sum())
    free = ~(frozen | ground)
    # columns: 3 per free vertex, then 1 per sliding vertex
    free_idx = np.flatnonzero(free)
    slide_idx = np.flatnonzero(sliding)
    n_free = free_idx.size
    rows_f = (3 * free_idx[:, None] + np.arange(3)).ravel()
    cols_f = np.arange(3 * n_free)
    vals_f = np.ones(3 * n_free)
    rows_s = (3 * slide_idx[:, None] + np.arange(3)).ravel()
    cols_s = np.repeat(3 * n_free + np.arange(slide_idx.size), 3)
    vals_s = slide_dirs[slide_idx].ravel()
    keep = vals_s != 0.0
    basis = sp.csr_matrix(
        (
            np.concatenate([vals_f, vals_s[keep]]),
            (np.concatenate([rows_f, rows_s[keep]]), np.concatenate([cols_f, cols_s[keep]])),
        ),
        shape=(3 * n, 3 * n_free + slide_idx.size),
    )
    base_flat = base.ravel().copy()
    base_flat[rows_f] = 0.0
    for_bounds = [(None, None)] * (3 * n_free) + [tuple(bounds_slide[i]) for i in slide_idx]
    return _Border(
        base=base_flat,
        basis=basis,
        bounds=for_bounds,
        moving=free | sliding,
        sliding=sliding,
        rectangle=rectangle,
    ), np.concatenate([x[free_idx].ravel(), slide_param[slide_idx]])


def _check_sides(border: _Border, x0: np.ndarray, ground: np.ndarray, min_len: float, scale: float) -> None:
    """Raise SolverError when a rectangle side is too short for its vertices."""
    if not border.sliding.any():
        return
    axes = border.rectangle["axes"]
    lo, hi = border.rectangle["lo"] / scale, border.rectangle["hi"] / scale
    gi = np.flatnonzero(ground)
    local = x0[gi][:, [0, 2]] @ axes.T
    for dim in range(2):
        for side_value in (lo[dim], hi[dim]):
            on = np.abs(local[:, dim] - side_value) <= _RECT_TOL
            count = int(on.sum())
            length = hi[1 - dim] - lo[1 - dim]
            if count >= 2 and (count - 1) * min_len > length * (1 + 1e-9):
                msg = (
                    f"optimize: min_edge_length {min_len * scale:.4g} m cannot be met: "
                    f"{count} ground vertices share a rectangle side of {length * scale:.4g} m"
                )
                raise SolverError(msg)


#: The penalty aims at ``min_edge_length * (1 + _EDGE_MARGIN)``, so that what it
#: leaves unmet of that target still meets ``min_edge_length``.
_EDGE_MARGIN = 1e-4
#: Accepted relative violation of ``|e|^2 >= min_edge_length^2`` after the solve.
_EDGE_TOL = 1e-6
#: Augmented Lagrangian: first penalty weight (per squared normalised length),
#: its growth when the violation does not drop fourfold in a round, and the
#: most rounds.
_PENALTY_START = 100.0
_PENALTY_GROWTH = 10.0
_MAX_ROUNDS = 10
#: L-BFGS-B: stop when every projected gradient component is below this
#: (dimensionless units); number of correction pairs kept.
_GTOL = 1e-6
_MEMORY = 10
#: Factor on ``tolerance`` for the penalty rounds after the first.
_LATER_FTOL = 1e-1


class _EdgeLengthPenalty:
    """Augmented-Lagrangian term for ``|x_a - x_b| >= target`` on edges.

    Each edge's constraint is written ``c_e >= 0``; with multipliers ``lam``
    and penalty weight ``mu`` the term is ``sum_e (max(0, lam_e - mu c_e)^2 -
    lam_e^2) / (2 mu)``: continuously differentiable and zero on edges that
    are long enough and carry no multiplier.

    - An edge between two ground vertices on the same rectangle side (one at
      least sliding) has a known direction ``s`` along the side (its start
      orientation), and its length is ``<e, s>``: the constraint is linear,
      ``c_e = <e, s> - target``. It keeps the vertices' order along the side
      whatever the step length (a constraint on ``|e|`` would let the solver
      jump a vertex over its neighbour).
    - Any other edge: ``c_e = target / 2 (1 - target^2 / |e|^2)``, unbounded
      as the edge shrinks.

    Both are ``|e| - target`` to first order at the target: a length, so the
    penalty's stiffness does not depend on how small ``target`` is.

    Parameters
    ----------
    edges : (m, 2) int64
    n : int
        Number of vertices.
    target : float
        Length aimed at (normalised units).
    directions : (m, 3) float64
        Unit ``s`` for the edges along a rectangle side, zero rows otherwise.
    """

    def __init__(self, edges: np.ndarray, n: int, target: float, directions: np.ndarray):
        m = len(edges)
        self.edges = edges
        self.size = m
        self.target = target
        self.scale = target  # relative violation: -c / scale
        self.target_sq = target**2
        self.directions = directions
        self.linear = np.any(directions != 0.0, axis=1)
        self.first, self.second = edges[:, 0].copy(), edges[:, 1].copy()
        # signed incidence (n, m): +1 at an edge's first end, -1 at its second
        self.incidence = sp.csr_matrix(
            (np.concatenate([np.ones(m), -np.ones(m)]), (edges.T.ravel(), np.tile(np.arange(m), 2))),
            shape=(n, m),
        )
        self._incidence = _RowSums(self.incidence)

    def constraint(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``c`` (m,), the edge vectors (m, 3) and squared lengths (m,) at ``x`` (n, 3)."""
        d = x.take(self.first, axis=0) - x.take(self.second, axis=0)
        # floored so that coinciding ends give a huge finite value, not inf
        sq = np.maximum(np.einsum("ec,ec->e", d, d), 1e-12 * self.target_sq)
        along = np.einsum("ec,ec->e", d, self.directions)
        c = np.where(self.linear, along - self.target, 0.5 * self.target * (1.0 - self.target_sq / sq))
        return c, d, sq

    def value_and_grad(self, x: np.ndarray, lam: np.ndarray, mu: float) -> tuple[float, np.ndarray]:
        """Penalty value and its gradient (n, 3) at ``x``."""
        c, d, sq = self.constraint(x)
        q = np.maximum(lam - mu * c, 0.0)  # -dP/dc
        value = float(q @ q - lam @ lam) / (2.0 * mu)
        # dP/de = -q dc/de: dc/de = target^3 e / |e|^4, or s
        dc = np.where(
            self.linear[:, None],
            self.directions,
            (self.target * self.target_sq / sq**2)[:, None] * d,
        )
        grad = self._incidence @ (-q[:, None] * dc)
        return value, grad


class _CornerAnglePenalty:
    """Augmented-Lagrangian term for ``alpha_k >= target_k`` on quad corners.

    Same form as :class:`_EdgeLengthPenalty`: with ``c_k = l_k (alpha_k -
    target_k)`` the term is ``sum_k (max(0, lam_k - mu c_k)^2 - lam_k^2) / (2
    mu)``. The lever ``l_k``, the geometric mean of the corner's two edge
    lengths in the template, turns the angle into a length (the sideways
    move of a corner's neighbour that changes ``alpha_k`` by ``c_k / l_k``), so
    the penalty is as stiff as the edge lengths' for the same weight ``mu``.

    Parameters
    ----------
    faces : (f, 4) int64
    n : int
        Number of vertices.
    target : (f, 4) float64
        Smallest angle of each corner (rad); corners with ``target <= 0`` are
        not constrained.
    lever : (f, 4) float64
        Positive lengths ``l_k``.
    """

    def __init__(self, faces: np.ndarray, n: int, target: np.ndarray, lever: np.ndarray):
        self.faces = faces
        self.mask = target > 0.0
        self.every = bool(self.mask.all())  # every corner has a floor: no masking
        self.target = target[self.mask]
        self.lever = lever[self.mask]
        self.size = int(self.target.size)
        self.scale = self.target * self.lever  # relative violation: -c / scale
        self.scatter = _scatter_matrix(faces.ravel(), n)
        self._scatter = _RowSums(self.scatter)
        self._around = _around(faces)

    def constraint(self, x: np.ndarray) -> tuple[np.ndarray]:
        """``c`` (m,) at ``x`` (n, 3)."""
        return (self.of_angles(_corner_angles(x, self.faces, self._around)[0]),)

    def of_angles(self, alpha: np.ndarray) -> np.ndarray:
        """``c`` (m,) from the corner angles ``alpha`` (f, 4)."""
        return ((alpha.ravel() if self.every else alpha[self.mask]) - self.target) * self.lever

    def on_angles(self, alpha: np.ndarray, lam: np.ndarray, mu: float) -> tuple[float, np.ndarray]:
        """Penalty value and its derivative (f, 4) w.r.t. the corner angles."""
        q = np.maximum(lam - mu * self.of_angles(alpha), 0.0)  # -dP/dc
        value = float(q @ q - lam @ lam) / (2.0 * mu)
        if self.every:
            return value, (-q * self.lever).reshape(self.mask.shape)
        d_alpha = np.zeros(self.mask.shape)
        d_alpha[self.mask] = -q * self.lever
        return value, d_alpha

    def value_and_grad(self, x: np.ndarray, lam: np.ndarray, mu: float) -> tuple[float, np.ndarray]:
        """Penalty value and its gradient (n, 3) at ``x``."""
        alpha, parts = _corner_angles(x, self.faces, self._around)
        value, d_alpha = self.on_angles(alpha, lam, mu)
        return value, self._scatter @ _angle_gradient(parts, d_alpha).reshape(-1, 3)


def _solve(
    energy: CageEnergy,
    edges: _EdgeLengthPenalty,
    angles: _CornerAnglePenalty,
    unpack,
    basis_t,
    z0,
    bounds,
    p,
):
    """Minimise the energy over the reduced unknowns under the inequalities.

    L-BFGS-B (bounds keep sliding vertices on their side) on the energy plus
    the augmented-Lagrangian terms of the edge lengths and the corner angles
    (one weight ``mu`` for both); the multipliers are updated and the weight
    raised until every constraint is within half ``_EDGE_MARGIN`` (relative)
    of its penalty's target, i.e. meets its bound itself (``min_edge_length``,
    the corner's smallest angle).

    Returns
    -------
    z : ndarray
        Reduced unknowns.
    result : OptimizeResult
        Of the last L-BFGS-B run.
    iterations, rounds : int
        L-BFGS-B iterations in total, penalty rounds.
    """
    lam_e = np.zeros(edges.size)
    lam_a = np.zeros(angles.size)
    mu = _PENALTY_START

    def angle_penalty(alpha):
        return angles.on_angles(alpha, lam_a, mu)

    def fun(z):
        x = unpack(z)
        value, grad = energy.value_and_grad(x, angle_penalty if angles.size else None)
        if edges.size:
            pv, pg = edges.value_and_grad(x, lam_e, mu)
            value += pv
            grad += pg
        return value, basis_t @ grad.ravel()

    z = z0
    iterations = 0
    rounds = 0
    previous = np.inf
    max_it = int(p["max_iterations"])
    while True:
        rounds += 1
        result = scipy.optimize.minimize(
            fun,
            z,
            jac=True,
            method="L-BFGS-B",
            bounds=bounds,
            options={
                "maxiter": max_it,
                # later rounds move edges by tiny amounts: their energy changes
                # are far below the first round's stopping threshold
                "ftol": p["tolerance"] * (1.0 if rounds == 1 else _LATER_FTOL),
                "gtol": _GTOL,
                "maxcor": _MEMORY,
            },
        )
        iterations += int(result.nit)
        z = result.x
        if not (edges.size or angles.size):
            break
        x = unpack(z)
        g_e = edges.constraint(x)[0]
        g_a = angles.constraint(x)[0]
        # relative to each target: |e| >= target (1 - margin / 2) = min_edge_length
        # (1 + margin / 2) to first order, the same for the angles
        violation = max(
            0.0,
            float(np.max(-g_e / edges.scale, initial=0.0)),
            float(np.max(-g_a / angles.scale, initial=0.0)),
        )
        if violation <= 0.5 * _EDGE_MARGIN or rounds >= _MAX_ROUNDS:
            break
        lam_e = np.maximum(lam_e - mu * g_e, 0.0)
        lam_a = np.maximum(lam_a - mu * g_a, 0.0)
        if violation > 0.25 * previous:
            mu *= _PENALTY_GROWTH
        previous = violation
    return z, result, iterations, rounds


def optimize_cage(mesh: ControlMesh, params: Mapping[str, Any] | None = None) -> ControlMesh:
    """Run the paper's mesh optimisation on ``mesh``.

    Parameters
    ----------
    mesh : ControlMesh
        Quad cage from a template (faces (f, 4)).
    params : mapping, optional
        Overrides of :data:`OPTIMIZE_DEFAULTS` (declared in :data:`OPTIMIZE_OPTIONS`).

    Returns
    -------
    ControlMesh
        Same topology; ``meta["optimize"]`` holds the quality figures before
        and after, the energy terms, L-BFGS-B iterations (all rounds),
        penalty rounds, the last run's status and message, and the time.

    Raises
    ------
    SolverError
        When a hard constraint cannot be met or the solver diverges.
    RecipeError
        On an unknown parameter.
    """
    from threadpoolctl import threadpool_limits

    # hundreds of small dense products: multithreaded BLAS only adds
    # contention (0.1 s with one thread, 0.5-1.3 s with two on a busy machine)
    with threadpool_limits(limits=1):
        return _optimize_cage(mesh, params)


def _checked_cage(mesh: ControlMesh) -> tuple[np.ndarray, np.ndarray]:
    """The cage's float vertices and quad faces; a SolverError for anything else."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if faces.ndim != 2 or faces.shape[1] != 4:
        msg = f"optimize: faces must be quads (f, 4), got shape {faces.shape}"
        raise SolverError(msg)
    if not np.all(np.isfinite(vertices)):
        msg = "optimize: the cage has non-finite vertex coordinates"
        raise SolverError(msg)
    return vertices, faces


@dataclass
class _Problem:
    """What the solver works on, in normalised coordinates (centred in x and z, unit mean edge)."""

    scale: float  # m per normalised unit
    shift: np.ndarray  # (3,) m, the centre subtracted (y stays: y = 0 is the ground)
    min_len: float  # the shortest allowed edge, normalised
    energy: CageEnergy
    border: _Border
    ground: np.ndarray  # (n,) bool
    c_edges: np.ndarray  # (m, 2) the edges with a moving end: length-constrained
    start_edges: np.ndarray  # (m, 3) those edges at the start
    on_side: np.ndarray  # (m,) bool: edges along a ground-rectangle side
    penalty: "_EdgeLengthPenalty"
    angle_floor: np.ndarray  # (f, 4) rad, 0 where a corner is free
    angles: "_CornerAnglePenalty"
    basis: _RowSums  # border.basis, for the products of every evaluation
    basis_t: _RowSums  # its transpose
    z0: np.ndarray
    bounds: scipy.optimize.Bounds

    def unpack(self, z: np.ndarray) -> np.ndarray:
        """(n, 3) normalised vertices of the unknowns ``z``."""
        return (self.border.base + self.basis @ z).reshape(-1, 3)

    def slack(self, x: np.ndarray) -> np.ndarray:
        """Relative slack of |e|^2 >= l^2 on the constrained edges (>= 0: met)."""
        e = x[self.c_edges[:, 0]] - x[self.c_edges[:, 1]]
        return np.einsum("ec,ec->e", e, e) / self.min_len**2 - 1.0


def _normalised_energy(mesh: ControlMesh, vertices, faces, edges, p) -> tuple[float, np.ndarray, np.ndarray, CageEnergy]:
    """Scale, shift, the normalised vertices and the cage's energy (weights relative to their peak)."""
    lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    scale = float(lengths.mean())
    shift = np.array([vertices[:, 0].mean(), 0.0, vertices[:, 2].mean()])
    x0 = (vertices - shift) / scale
    weights = np.asarray(mesh.vertex_weights, dtype=np.float64)
    peak = float(weights.max()) if weights.size else 0.0
    weights = np.clip(weights / peak, 0.0, 1.0) if peak > 0 else np.zeros(len(vertices))
    energy = CageEnergy.build(
        x0,
        faces,
        weights,
        (np.asarray(mesh.plane_points, dtype=np.float64) - shift) / scale,
        np.asarray(mesh.plane_normals, dtype=np.float64),
        p,
    )
    return scale, shift, x0, energy


def _side_directions(border: _Border, c_edges, start_edges, ground) -> tuple[np.ndarray, np.ndarray]:
    """Edges along a rectangle side (both ends ground, one sliding, one rectangle coordinate shared) and their direction along it."""
    on_side = border.sliding[c_edges[:, 0]] | border.sliding[c_edges[:, 1]]
    on_side &= ground[c_edges[:, 0]] & ground[c_edges[:, 1]]
    directions = np.zeros((len(c_edges), 3))
    if on_side.any():
        axes = border.rectangle["axes"]
        local = start_edges[:, [0, 2]] @ axes.T  # (m, 2) in the rectangle frame
        along = np.argmax(np.abs(local), axis=1)
        rows = np.arange(len(c_edges))
        on_side &= np.abs(local[rows, 1 - along]) <= _RECT_TOL * np.abs(local[rows, along])
        sign = np.sign(local[rows, along])
        directions[:, [0, 2]] = (sign[:, None] * axes[along]) * on_side[:, None]
    return on_side, directions


def _angle_penalty(x0, faces, border: _Border, p) -> tuple[np.ndarray, "_CornerAnglePenalty"]:
    """Corner angles: none below min(its angle in the template, as cage_quality measures it, and the floor).

    Only corners whose angle can change (one of their three vertices moves)
    and whose angle is defined get a floor.
    """
    template_angles, (ab, _, _, _) = _corner_angles(x0, faces)
    lever = np.sqrt(np.linalg.norm(ab[0], axis=-1) * np.linalg.norm(ab[1], axis=-1))
    can_change = border.moving[faces] | border.moving[faces[:, _PREV]] | border.moving[faces[:, _NEXT]]
    can_change &= lever > 1e-9
    angle_floor = np.where(can_change, np.minimum(template_angles, np.radians(p["min_corner_angle_deg"])), 0.0)
    return angle_floor, _CornerAnglePenalty(faces, len(x0), angle_floor * (1.0 + _EDGE_MARGIN), lever)


def _build_problem(mesh: ControlMesh, vertices, faces, p) -> _Problem:
    """Normalise the cage, build its energy, the border's unknowns and the hard constraints' penalties."""
    n = len(vertices)
    edges = mesh_edges(faces)
    scale, shift, x0, energy = _normalised_energy(mesh, vertices, faces, edges, p)
    min_len = p["min_edge_length"] / scale
    ground = np.asarray(mesh.ground, bool)
    fixed = np.asarray(mesh.fixed, bool)
    border, z0 = _build_border(
        x0, ground, fixed, slide=p["slide_border"], scale=scale, gap=min_len * (1.0 + _EDGE_MARGIN)
    )
    _check_sides(border, x0, ground, min_len, scale)

    # edge-length inequalities on edges with a moving end
    moving_edge = border.moving[edges[:, 0]] | border.moving[edges[:, 1]]
    c_edges = edges[moving_edge]
    lower = np.array([-np.inf if b[0] is None else b[0] for b in border.bounds], dtype=np.float64)
    upper = np.array([np.inf if b[1] is None else b[1] for b in border.bounds], dtype=np.float64)
    z0 = np.clip(z0, lower, upper)
    x_start = (border.base + border.basis @ z0).reshape(n, 3)
    start_edges = x_start[c_edges[:, 0]] - x_start[c_edges[:, 1]]
    start_lengths = np.linalg.norm(start_edges, axis=1)
    if np.any(start_lengths <= 1e-9):
        a, b = c_edges[np.argmin(start_lengths)]
        msg = f"optimize: the cage has a zero-length edge between vertices {a} and {b}; cannot optimise it"
        raise SolverError(msg)
    on_side, directions = _side_directions(border, c_edges, start_edges, ground)
    angle_floor, angles = _angle_penalty(x0, faces, border, p)
    return _Problem(
        scale=scale,
        shift=shift,
        min_len=min_len,
        energy=energy,
        border=border,
        ground=ground,
        c_edges=c_edges,
        start_edges=start_edges,
        on_side=on_side,
        penalty=_EdgeLengthPenalty(c_edges, n, min_len * (1.0 + _EDGE_MARGIN), directions),
        angle_floor=angle_floor,
        angles=angles,
        basis=_RowSums(border.basis),
        basis_t=_RowSums(border.basis.T),
        z0=z0,
        bounds=scipy.optimize.Bounds(lower, upper),
    )


def _check_solution(problem: _Problem, x, faces, e_start: float, e_total: float, result, iterations: int, outer: int, p) -> None:
    """Refuse a result that diverged or misses a hard constraint (edge lengths, corner angles, side order)."""
    if not np.all(np.isfinite(x)) or not np.isfinite(e_total):
        msg = f"optimize: the solver diverged (non-finite result; L-BFGS-B status {result.status}: {result.message})"
        raise SolverError(msg)
    c_edges = problem.c_edges
    m = len(c_edges)
    worst = float(problem.slack(x).min()) if m else 0.0
    # relative violation of |e|^2 >= l^2, as a length: |e| >= l (1 - tol)
    if m and worst < -_EDGE_TOL:
        short = float(np.sqrt(max(worst + 1.0, 0.0)) * p["min_edge_length"])
        msg = (
            f"optimize: hard constraint not met: an edge is {short:.4g} m long, "
            f"min_edge_length is {p['min_edge_length']:.4g} m after {outer} penalty rounds, "
            f"{iterations} L-BFGS-B iterations (max_iterations {p['max_iterations']}; "
            f"status {result.status}: {result.message})"
        )
        raise SolverError(msg)
    # corner angles, relative: alpha >= floor (1 - tol)
    angle_floor = problem.angle_floor
    if problem.angles.size:
        alpha = _corner_angles(x, faces)[0]
        ratio = np.where(angle_floor > 0.0, alpha / np.where(angle_floor > 0.0, angle_floor, 1.0), np.inf)
        if ratio.min() < 1.0 - _EDGE_TOL:
            f, k = np.unravel_index(np.argmin(ratio), ratio.shape)
            msg = (
                f"optimize: hard constraint not met: corner {k} of face {f} has an angle of "
                f"{np.degrees(alpha[f, k]):.4g} deg, its floor (min of the template's angle and "
                f"min_corner_angle_deg {p['min_corner_angle_deg']:.4g}) is {np.degrees(angle_floor[f, k]):.4g} deg "
                f"after {outer} penalty rounds, {iterations} L-BFGS-B iterations "
                f"(status {result.status}: {result.message})"
            )
            raise SolverError(msg)
    # sliding vertices keep their order along their side (the side edges'
    # constraints are linear in the signed length; a guard all the same)
    end_edges = x[c_edges[:, 0]] - x[c_edges[:, 1]]
    reversed_ = problem.on_side & (np.einsum("ec,ec->e", problem.start_edges, end_edges) <= 0.0)
    if reversed_.any():
        a, b = c_edges[np.flatnonzero(reversed_)[0]]
        msg = f"optimize: ground vertices {a} and {b} passed each other on their rectangle side (solver failure)"
        raise SolverError(msg)
    x_start = problem.unpack(problem.z0)
    if e_total > e_start * (1 + 1e-9) and worst >= 0 and (problem.slack(x_start).min() if m else 0.0) >= 0:
        msg = (
            f"optimize: the solver diverged: energy rose from {e_start:.6g} to {e_total:.6g} "
            f"(L-BFGS-B status {result.status}: {result.message})"
        )
        raise SolverError(msg)


def _optimize_cage(mesh: ControlMesh, params: Mapping[str, Any] | None) -> ControlMesh:
    start = time.perf_counter()
    p = refiner_params("optimize", OPTIMIZE_OPTIONS, params)
    vertices, faces = _checked_cage(mesh)
    problem = _build_problem(mesh, vertices, faces, p)
    e_start, _ = problem.energy.value_and_grad(problem.unpack(problem.z0))
    quality_before = cage_quality(vertices, faces)
    z, result, iterations, outer = _solve(
        problem.energy, problem.penalty, problem.angles, problem.unpack, problem.basis_t, problem.z0, problem.bounds, p
    )
    x = problem.unpack(z)
    e_end = problem.energy.terms(x)
    e_total = float(sum(e_end.values()))
    _check_solution(problem, x, faces, e_start, e_total, result, iterations, outer, p)

    out = x * problem.scale + problem.shift
    # the ground rows are exact by construction; write them without round-off
    out[problem.ground, 1] = 0.0
    meta = dict(mesh.meta)
    meta["optimize"] = {
        "before": quality_before,
        "after": cage_quality(out, faces),
        "energy_before": float(e_start),
        "energy_after": e_total,
        "terms_after": e_end,
        "iterations": int(iterations),
        "penalty_rounds": int(outer),
        "status": int(result.status),
        "message": str(result.message),
        "seconds": time.perf_counter() - start,
        "params": p,
    }
    return replace(mesh, vertices=out, meta=meta)


class OptimizeRefiner:
    """The ``optimize`` refiner: the paper's Section 5.3 mesh optimisation."""

    name = "optimize"
    description = "Mesh optimisation of the paper (Laplacian, angle, vertex and plane terms; L-BFGS-B)"
    options = OPTIMIZE_OPTIONS

    def refine(
        self,
        mesh: ControlMesh,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        *,
        params: Mapping[str, Any] | None = None,
    ) -> ControlMesh:
        """Return the optimised cage (same topology); bodies are not used."""
        return optimize_cage(mesh, params)
