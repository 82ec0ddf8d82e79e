"""Tests of the ``optimize`` refiner (paper Section 5.3, Appendix B)."""

from __future__ import annotations

import numpy as np
import pytest

from seatkit.body import list_poses
from seatkit.errors import RecipeError, SolverError
from seatkit.model import ControlMesh
from seatkit.template.quad_grid import grid_faces, grid_ring
from seatkit.refine.optimize import (
    OPTIMIZE_DEFAULTS,
    CageEnergy,
    OptimizeRefiner,
    _build_border,
    _corner_angles,
    _CornerAnglePenalty,
    _RowSums,
    _EdgeLengthPenalty,
    optimize_cage,
)
from seatkit.refine.quality import cage_quality, face_angles, mesh_edges

ROWS, COLS = 11, 7  # faces, like the chair: 7 x 3 grid plus two border rings

#: (z, y) of each vertex row from the front ground edge to the back one, m
PROFILE = np.array(
    [
        (0.70, 0.00),  # ground
        (0.62, 0.06),  # border ring
        (0.58, 0.20),  # feet / shins
        (0.52, 0.36),
        (0.42, 0.46),  # knees
        (0.20, 0.45),  # thighs
        (0.00, 0.42),  # hips
        (-0.12, 0.52),  # lumbar
        (-0.17, 0.72),  # lower back
        (-0.22, 0.95),  # upper back
        (-0.30, 1.00),  # border ring
        (-0.40, 0.00),  # ground
    ]
)
XS = np.array([-0.35, -0.25, -0.15, -0.05, 0.05, 0.15, 0.25, 0.35])


def chair_cage(noise: float = 0.0, seed: int = 0, xs: np.ndarray = XS) -> ControlMesh:
    """A synthetic chair-like cage (12 x 8 vertices) with planes per face.

    Planes are fitted to the unperturbed faces; ``noise`` (m) then perturbs
    every non-ground vertex. ``xs`` (m) are the vertex columns' x (wider:
    a bench-like cage with the same profile).
    """
    rows, cols = len(PROFILE) - 1, len(xs) - 1
    z = np.repeat(PROFILE[:, 0][:, None], len(xs), axis=1)
    y = np.repeat(PROFILE[:, 1][:, None], len(xs), axis=1)
    x = np.repeat(xs[None, :], len(PROFILE), axis=0)
    # ground columns: on the x = xs[0] and xs[-1] sides, y = 0
    y[:, [0, -1]] = 0.0
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    faces = grid_faces(rows, cols)
    ground = grid_ring(rows, cols, 0)
    # best-fit plane of each unperturbed face
    corners = vertices[faces]
    centre = corners.mean(axis=1)
    _, _, vt = np.linalg.svd(corners - centre[:, None, :])
    normals = vt[:, 2, :]
    normals *= np.sign(normals[:, 1:2] + 1e-12)
    weights = np.where(ground, 0.0, np.where(grid_ring(rows, cols, 1), 0.3, 1.0))
    rng = np.random.default_rng(seed)
    moved = vertices + np.where(ground[:, None], 0.0, noise * rng.standard_normal(vertices.shape))
    segments = np.where(grid_ring(rows, cols, 0)[faces].all(axis=1), -1, 0)
    structural = np.zeros(len(faces), bool)
    structural[np.flatnonzero(ground[faces].any(axis=1))] = True
    planes_p = np.where(structural[:, None], np.nan, centre)
    planes_n = np.where(structural[:, None], np.nan, normals)
    return ControlMesh(
        vertices=moved,
        faces=faces,
        face_segments=np.where(structural, -1, segments),
        plane_points=planes_p,
        plane_normals=planes_n,
        vertex_weights=weights,
        fixed=ground.copy(),
        ground=ground,
    )


def _energy(mesh, params=None):
    p = dict(OPTIMIZE_DEFAULTS, **(params or {}))
    w = mesh.vertex_weights / mesh.vertex_weights.max()
    rest = mesh.vertices + 0.01  # a rest state different from x: D_V non-zero
    return CageEnergy.build(rest, mesh.faces, w, mesh.plane_points, mesh.plane_normals, p)


TERM_PARAMS = {
    "laplacian": {"lambda_regular": 0.0, "lambda_max_angle": 0.0, "lambda_vertex": 0.0, "lambda_plane": 0.0},
    "regular": {"lambda_laplacian": 0.0, "lambda_max_angle": 0.0, "lambda_vertex": 0.0, "lambda_plane": 0.0},
    "max_angle": {"lambda_laplacian": 0.0, "lambda_regular": 0.0, "lambda_vertex": 0.0, "lambda_plane": 0.0},
    "vertex": {"lambda_laplacian": 0.0, "lambda_regular": 0.0, "lambda_max_angle": 0.0, "lambda_plane": 0.0},
    "plane": {"lambda_laplacian": 0.0, "lambda_regular": 0.0, "lambda_max_angle": 0.0, "lambda_vertex": 0.0},
    "all": {},
}


def _central_differences(f, x, h=1e-6):
    """Gradient of the scalar ``f`` at ``x`` (any shape) by central differences."""
    numeric = np.zeros_like(x)
    for k in np.ndindex(x.shape):
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        numeric[k] = (f(xp) - f(xm)) / (2 * h)
    return numeric


@pytest.mark.parametrize("term", sorted(TERM_PARAMS))
def test_gradient_matches_central_differences(term):
    mesh = chair_cage(noise=0.02, seed=3)
    energy = _energy(mesh, TERM_PARAMS[term])
    x = mesh.vertices
    value, grad = energy.value_and_grad(x)
    assert value > 0.0
    numeric = _central_differences(lambda y: energy.value_and_grad(y)[0], x)
    rel = np.linalg.norm(grad - numeric) / np.linalg.norm(numeric)
    assert rel < 1e-5, f"{term}: relative gradient error {rel:.2e}"


def test_row_sums_give_scipys_sparse_products():
    """The energy's products without scipy.sparse: every matrix it uses, and its transposes, on vectors and (m, 3) arrays."""
    import scipy.sparse as sp

    mesh = chair_cage(noise=0.02, seed=5)
    energy = _energy(mesh, {})
    rng = np.random.default_rng(0)
    signed = sp.random(40, 96, density=0.1, format="csr", random_state=1, data_rvs=lambda k: rng.standard_normal(k))
    for matrix in (energy.laplacian, energy.corner_scatter, energy.plane_scatter, signed):
        for m in (matrix, matrix.T):
            for shape in ((m.shape[1],), (m.shape[1], 3)):
                x = rng.standard_normal(shape)
                fast, reference = _RowSums(m) @ x, m @ x
                assert fast.shape == reference.shape
                # the same products added in the same order (equal to the bit
                # where neither side fuses a multiply-add)
                np.testing.assert_allclose(fast, reference, rtol=1e-13, atol=1e-13 * np.abs(x).max())


def test_corner_angles_match_the_quality_figures():
    mesh = chair_cage(noise=0.03, seed=6)
    alpha, (ab, sin_part, cos_part, squares) = _corner_angles(mesh.vertices, mesh.faces)
    np.testing.assert_allclose(alpha, face_angles(mesh.vertices, mesh.faces), atol=1e-12)
    # the parts: edges to the previous and next corner, |a x b|, a . b, |a|^2 and |b|^2
    corner = mesh.vertices[mesh.faces]
    a, b = np.roll(corner, 1, axis=1) - corner, np.roll(corner, -1, axis=1) - corner
    np.testing.assert_allclose(ab[0], a, atol=1e-15)
    np.testing.assert_allclose(ab[1], b, atol=1e-15)
    np.testing.assert_allclose(sin_part, np.linalg.norm(np.cross(a, b), axis=-1), rtol=1e-12)
    np.testing.assert_allclose(cos_part, np.sum(a * b, axis=-1), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(squares, [np.sum(a * a, axis=-1), np.sum(b * b, axis=-1)], rtol=1e-12)


def test_terms_vanish_where_expected():
    mesh = chair_cage()
    p = dict(OPTIMIZE_DEFAULTS)
    w = mesh.vertex_weights
    energy = CageEnergy.build(mesh.vertices, mesh.faces, w, mesh.plane_points, mesh.plane_normals, p)
    terms = energy.terms(mesh.vertices)
    assert terms["vertex"] == 0.0
    # planes were fitted to these faces: only the non-planarity remains
    assert terms["plane"] < 1e-3
    # a flat unit square grid: no angle-sum error, max-angle term = pi^2 per face
    flat = np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0), indexing="ij"), -1).reshape(-1, 2)
    v = np.column_stack([flat[:, 1], np.zeros(len(flat)), flat[:, 0]])
    f = grid_faces(3, 2)
    e = CageEnergy.build(v, f, np.ones(len(v)), np.full((6, 3), np.nan), np.full((6, 3), np.nan), p)
    t = e.terms(v)
    assert t["regular"] == pytest.approx(0.0, abs=1e-24)
    assert t["max_angle"] == pytest.approx(p["lambda_max_angle"] * 6 * 4 * (np.pi / 2) ** 2)
    assert t["plane"] == 0.0


def test_optimize_improves_perturbed_cage_and_keeps_constraints():
    mesh = chair_cage(noise=0.02, seed=1)
    out = OptimizeRefiner().refine(mesh, [], [], params={"min_edge_length": 0.03})
    assert out.faces is mesh.faces or np.array_equal(out.faces, mesh.faces)
    assert out.vertices.shape == mesh.vertices.shape
    before, after = cage_quality(mesh.vertices, mesh.faces), cage_quality(out.vertices, out.faces)
    assert after["planarity_mean"] < before["planarity_mean"]
    assert after["min_angle_deg"] > before["min_angle_deg"]
    assert after["regularity_deg"] < before["regularity_deg"]
    report = out.meta["optimize"]
    assert report["before"] == before
    assert report["after"] == after
    assert report["energy_after"] < report["energy_before"]
    # ground vertices: y = 0 and on the rectangle x = +-0.35 or z in {0.7, -0.4}
    g = out.vertices[mesh.ground]
    assert np.abs(g[:, 1]).max() <= 1e-9
    on_x = np.abs(np.abs(g[:, 0]) - 0.35) <= 1e-9
    on_z = (np.abs(g[:, 2] - 0.7) <= 1e-9) | (np.abs(g[:, 2] + 0.4) <= 1e-9)
    assert np.all(on_x | on_z)
    assert np.all((g[:, 2] >= -0.4 - 1e-9) & (g[:, 2] <= 0.7 + 1e-9))
    assert np.all((g[:, 0] >= -0.35 - 1e-9) & (g[:, 0] <= 0.35 + 1e-9))
    # ground vertices slid only along their side: the fixed coordinate is unchanged
    g0 = mesh.vertices[mesh.ground]
    assert np.all(np.isclose(g[:, 0], g0[:, 0], atol=1e-9) | np.isclose(g[:, 2], g0[:, 2], atol=1e-9))
    # minimal edge length
    e = mesh_edges(out.faces)
    lengths = np.linalg.norm(out.vertices[e[:, 0]] - out.vertices[e[:, 1]], axis=1)
    assert lengths.min() >= 0.03 * (1 - 1e-6)
    # the data term keeps the supporting (weight 1) control points near the template
    moved = np.linalg.norm(out.vertices - mesh.vertices, axis=1)
    assert moved[mesh.vertex_weights == 1.0].max() < 0.05


def test_min_edge_length_is_enforced_when_active():
    mesh = chair_cage(noise=0.0)
    e = mesh_edges(mesh.faces)
    lengths = np.linalg.norm(mesh.vertices[e[:, 0]] - mesh.vertices[e[:, 1]], axis=1)
    target = 0.09  # longer than several edges of the template
    assert (lengths < target).sum() > 5
    out = optimize_cage(mesh, {"min_edge_length": target})
    after = np.linalg.norm(out.vertices[e[:, 0]] - out.vertices[e[:, 1]], axis=1)
    moving = ~(mesh.fixed[e[:, 0]] & mesh.fixed[e[:, 1]]) | True
    assert after[moving].min() >= target * (1 - 1e-6)


def test_optimize_is_deterministic():
    mesh = chair_cage(noise=0.02, seed=5)
    a = optimize_cage(mesh)
    b = optimize_cage(mesh)
    assert np.array_equal(a.vertices, b.vertices)


def test_unmeetable_edge_length_raises_solver_error():
    mesh = chair_cage(noise=0.0)
    # 12 ground vertices share a 1.05 m side: 0.2 m apart cannot fit
    with pytest.raises(SolverError, match="min_edge_length"):
        optimize_cage(mesh, {"min_edge_length": 0.2})


def test_ground_off_rectangle_raises_solver_error():
    mesh = chair_cage()
    v = mesh.vertices.copy()
    v[np.flatnonzero(mesh.ground)[3], 0] += 0.05  # off the front side, inside
    v[np.flatnonzero(mesh.ground)[3], 2] -= 0.05
    with pytest.raises(SolverError, match="rectangle"):
        optimize_cage(mesh.with_vertices(v))


def test_unknown_parameter_is_a_recipe_error():
    with pytest.raises(RecipeError, match="lambda_laplace"):
        optimize_cage(chair_cage(), {"lambda_laplace": 1.0})
    with pytest.raises(RecipeError, match=r"^refiners.optimize.lambda_plane: expected a number from 0 to 1e\+06, got 'big'$"):
        optimize_cage(chair_cage(), {"lambda_plane": "big"})


def test_edge_length_penalty_gradient_matches_central_differences():
    rng = np.random.default_rng(7)
    x = rng.standard_normal((12, 3))
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [8, 9], [9, 10], [10, 11], [0, 11]])
    lengths = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
    target = float(np.median(lengths))  # about half the edges too short
    # three edges "along a side": put both ends on a line, direction = start orientation
    directions = np.zeros((len(edges), 3))
    for k, (a, b) in enumerate(edges[[4, 5, 8]]):
        s = np.array([1.0, 0.0, 0.0]) if k != 1 else np.array([0.0, 0.0, -1.0])
        x[b] = x[a] - (0.5 + k) * target * s  # e = x_a - x_b = (0.5 + k) target s
        directions[[4, 5, 8][k]] = s
    lengths = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
    penalty = _EdgeLengthPenalty(edges, len(x), target, directions)
    c = penalty.constraint(x)[0]
    assert np.all((c >= 0) == (lengths >= target))
    # along a side the constraint is the signed length minus the target
    assert np.allclose(c[[4, 5, 8]], lengths[[4, 5, 8]] - target)
    # elsewhere |e| - target to first order at the target
    near = x.copy()
    a, b = edges[0]
    near[b] = near[a] - (1.0 + 1e-6) * target * (x[a] - x[b]) / lengths[0]
    assert penalty.constraint(near)[0][0] == pytest.approx(1e-6 * target, rel=1e-4)
    # multipliers on some edges, zero on others; an edge long enough with a multiplier too
    lam = np.where(np.arange(len(edges)) % 3 == 0, 0.0, 0.7)
    mu = 3.0
    value, grad = penalty.value_and_grad(x, lam, mu)
    assert np.isfinite(value)
    numeric = _central_differences(lambda y: penalty.value_and_grad(y, lam, mu)[0], x)
    rel = np.linalg.norm(grad - numeric) / np.linalg.norm(numeric)
    assert rel < 1e-6, f"relative gradient error {rel:.2e}"
    # zero for edges long enough and without multiplier; unbounded as an edge shrinks
    assert penalty.value_and_grad(x * 10.0, np.zeros(len(edges)), mu)[0] == 0.0
    y = x.copy()
    y[1] = y[0] + 1e-4 * (y[1] - y[0])
    assert penalty.value_and_grad(y, np.zeros(len(edges)), mu)[0] > 1e6
    # a side edge whose end jumped over its neighbour is penalised more than a short one
    lam0 = np.zeros(len(edges))
    a, b = edges[8]
    short, flipped = x.copy(), x.copy()
    short[b] = x[a] - 0.3 * (x[a] - x[b])  # 0.75 target
    flipped[b] = x[a] + (x[a] - x[b])
    assert penalty.value_and_grad(flipped, lam0, mu)[0] > penalty.value_and_grad(short, lam0, mu)[0]


def test_reduced_gradient_through_the_border_parametrisation():
    mesh = chair_cage(noise=0.02, seed=2)
    energy = _energy(mesh)
    border, z0 = _build_border(mesh.vertices, mesh.ground, mesh.fixed, slide=True, scale=1.0, gap=0.02)
    n = len(mesh.vertices)
    sliding = np.flatnonzero(border.sliding)
    assert sliding.size == mesh.ground.sum() - 4  # every ground vertex but the 4 corners
    assert np.array_equal(border.moving, ~mesh.ground | border.sliding)

    def unpack(z):
        return (border.base + border.basis @ z).reshape(n, 3)

    assert np.allclose(unpack(z0), mesh.vertices, atol=1e-12)
    # a sliding vertex's bounds stop the minimal edge length short of a corner vertex
    lower = np.array([b[0] for b in border.bounds[-sliding.size :]])
    upper = np.array([b[1] for b in border.bounds[-sliding.size :]])
    assert np.allclose(np.sort(np.unique(np.round(lower, 9))), [-0.4 + 0.02, -0.35 + 0.02])
    assert np.allclose(np.sort(np.unique(np.round(upper, 9))), [0.35 - 0.02, 0.7 - 0.02])
    basis_t = border.basis.T.tocsr()
    _, grad_x = energy.value_and_grad(unpack(z0))
    grad_z = basis_t @ grad_x.ravel()
    numeric = _central_differences(lambda z: energy.value_and_grad(unpack(z))[0], z0)
    rel = np.linalg.norm(grad_z - numeric) / np.linalg.norm(numeric)
    assert rel < 1e-5, f"relative gradient error {rel:.2e}"
    # moving a sliding unknown moves its vertex along its side only, at y = 0
    z = z0.copy()
    z[-1] += 0.05
    moved = np.linalg.norm(unpack(z) - unpack(z0), axis=1)
    assert np.flatnonzero(moved > 0).tolist() == [sliding[-1]]
    assert unpack(z)[sliding[-1], 1] == 0.0


@pytest.mark.parametrize(("seed", "min_edge_length"), [(4, 0.09), (1, 0.005), (1, 0.0001)])
def test_sliding_vertices_keep_their_order(seed, min_edge_length):
    """Ground vertices pile up at the minimal length; they never pass each other."""
    mesh = chair_cage(noise=0.02, seed=seed)
    out = optimize_cage(mesh, {"min_edge_length": min_edge_length})
    e = mesh_edges(mesh.faces)
    on_ground = e[mesh.ground[e[:, 0]] & mesh.ground[e[:, 1]]]
    before = mesh.vertices[on_ground[:, 1]] - mesh.vertices[on_ground[:, 0]]
    after = out.vertices[on_ground[:, 1]] - out.vertices[on_ground[:, 0]]
    assert np.all(np.einsum("ec,ec->e", before, after) > 0.0)
    lengths = np.linalg.norm(out.vertices[e[:, 0]] - out.vertices[e[:, 1]], axis=1)
    assert lengths.min() >= min_edge_length * (1 - 1e-6)
    report = out.meta["optimize"]
    assert report["penalty_rounds"] >= 1
    assert report["iterations"] >= report["penalty_rounds"]
    assert report["seconds"] > 0.0
    assert report["energy_after"] < report["energy_before"]


def test_iterations_do_not_grow_with_the_cage_width():
    """A cage three times as wide (bench-like) needs about as many iterations."""
    narrow = optimize_cage(chair_cage(noise=0.02, seed=6))
    wide_xs = np.linspace(-1.05, 1.05, 22)  # 0.1 m columns, like XS
    wide = optimize_cage(chair_cage(noise=0.02, seed=6, xs=wide_xs))
    n_narrow, n_wide = narrow.meta["optimize"]["iterations"], wide.meta["optimize"]["iterations"]
    assert n_wide <= 2 * n_narrow, (n_narrow, n_wide)
    after = wide.meta["optimize"]["after"]
    before = wide.meta["optimize"]["before"]
    assert after["planarity_mean"] < before["planarity_mean"]
    assert after["regularity_deg"] < before["regularity_deg"]
    assert after["min_edge_length"] >= 0.02 * (1 - 1e-6)


def _angle_penalty(mesh):
    """A corner-angle penalty on ``mesh``: about a third of the corners too small."""
    x = mesh.vertices
    alpha = face_angles(x, mesh.faces)
    target = np.where(np.arange(alpha.size).reshape(alpha.shape) % 4 == 3, 0.0, alpha * 1.05)  # some unconstrained
    target[alpha > np.median(alpha)] *= 0.9  # these are met
    corner = x[mesh.faces]
    lever = np.sqrt(
        np.linalg.norm(np.roll(corner, 1, axis=1) - corner, axis=-1)
        * np.linalg.norm(np.roll(corner, -1, axis=1) - corner, axis=-1)
    )
    return _CornerAnglePenalty(mesh.faces, len(x), target, lever), alpha, target, lever


def test_corner_angle_penalty_gradient_matches_central_differences():
    mesh = chair_cage(noise=0.02, seed=3)
    x = mesh.vertices
    penalty, alpha, target, lever = _angle_penalty(mesh)
    active = target > 0.0
    assert penalty.size == active.sum() and 0 < penalty.size < alpha.size
    c = penalty.constraint(x)[0]
    assert np.allclose(c, ((alpha - target) * lever)[active])
    assert (c < 0).sum() > 50 and (c > 0).sum() > 50
    # multipliers on some corners (met or not), zero on others
    lam = np.where(np.arange(penalty.size) % 3 == 0, 0.0, 0.4)
    mu = 30.0
    value, grad = penalty.value_and_grad(x, lam, mu)
    assert np.isfinite(value) and value != 0.0
    numeric = _central_differences(lambda y: penalty.value_and_grad(y, lam, mu)[0], x)
    rel = np.linalg.norm(grad - numeric) / np.linalg.norm(numeric)
    assert rel < 1e-6, f"relative gradient error {rel:.2e}"
    # zero where every corner is wide enough and carries no multiplier
    assert penalty.value_and_grad(x, np.zeros(penalty.size), mu)[0] > 0.0
    wide = _CornerAnglePenalty(mesh.faces, len(x), np.where(active, 0.5 * alpha, 0.0), lever)
    zero_value, zero_grad = wide.value_and_grad(x, np.zeros(wide.size), mu)
    assert zero_value == 0.0 and not zero_grad.any()
    # inside the energy (sharing its angles) it adds exactly its own value and gradient
    energy = _energy(mesh)
    e_value, e_grad = energy.value_and_grad(x)
    both_value, both_grad = energy.value_and_grad(x, lambda a: penalty.on_angles(a, lam, mu))
    assert both_value == pytest.approx(e_value + value, rel=1e-13)
    assert np.allclose(both_grad, e_grad + grad, rtol=1e-12, atol=1e-12)


def test_corner_angles_keep_their_floor():
    """No corner ends below min(its template angle, min_corner_angle_deg)."""
    # on this cage the free optimum closes a corner face with three ground
    # vertices below the template's smallest angle, as on crossed-legs-ankles
    mesh = chair_cage(noise=0.02, seed=3)
    template = np.degrees(face_angles(mesh.vertices, mesh.faces))
    free = optimize_cage(mesh, {"min_corner_angle_deg": 0.0}).meta["optimize"]
    assert free["after"]["min_angle_deg"] < free["before"]["min_angle_deg"] - 1.0
    out = optimize_cage(mesh)
    report = out.meta["optimize"]
    assert report["after"]["min_angle_deg"] >= report["before"]["min_angle_deg"]
    assert report["after"]["planarity_mean"] < report["before"]["planarity_mean"]
    assert report["after"]["regularity_deg"] < report["before"]["regularity_deg"]
    assert report["energy_after"] <= free["energy_after"] * (1 + 1e-3)
    # a floor that binds on many corners: each meets it, where the free run does not
    floor = 75.0
    bound = np.minimum(template, floor)
    free_angles = np.degrees(face_angles(optimize_cage(mesh, {"min_corner_angle_deg": 0.0}).vertices, mesh.faces))
    assert (free_angles < bound).sum() >= 5
    out = optimize_cage(mesh, {"min_corner_angle_deg": floor})
    angles = np.degrees(face_angles(out.vertices, mesh.faces))
    assert np.all(angles >= bound * (1 - 1e-6))
    assert out.meta["optimize"]["penalty_rounds"] >= 2


#: The supportable library poses.
LIBRARY_POSES = [info.name for info in list_poses() if info.supported]


@pytest.mark.parametrize("pose", LIBRARY_POSES)
def test_optimize_improves_every_quality_figure_on_the_library_chairs(seated, pose):
    from seatkit.plugins import get_plugin_manager

    registry = get_plugin_manager(autoload=False).registry
    body, pressure = seated[pose]
    chair = registry.get("template", "chair").fit([body], [pressure])
    report = OptimizeRefiner().refine(chair, [body], [pressure]).meta["optimize"]
    before, after = report["before"], report["after"]
    assert after["planarity_mean"] < before["planarity_mean"]
    assert after["regularity_deg"] < before["regularity_deg"]
    assert after["min_angle_deg"] >= before["min_angle_deg"]
    assert after["min_edge_length"] >= 0.02 * (1 - 1e-6)
