"""The pressure QP on synthetic bodies: physical invariants and independent checks."""

from __future__ import annotations

import numpy as np
import pytest

from seatkit.constants import GRAVITY
from seatkit.errors import RecipeError, InfeasibleSupportError, InputError
from seatkit.model import Body
from seatkit.pressure import QPPressureSolver, contact_from_surface, solve_pressure
from seatkit.geometry.normals import vertex_normals
from seatkit.pressure.areas import mixed_voronoi_areas
from seatkit.pressure.assembly import subtree_matrix
from seatkit.pressure.synthetic import capsule, seated_capsule_body
from seatkit.pressure.weights import DEFAULT_WEIGHT_CAP, local_reaction_weights, tangent_frames
from seatkit.skeleton import N_SEGMENTS, PARENTS


@pytest.fixture(scope="module")
def body():
    return seated_capsule_body(resolution=1)


@pytest.fixture(scope="module")
def field(body):
    return solve_pressure(body, exclude=[])


def _objective(body, field, lam):
    """The paper's Eq. 4 recomputed from a field: c_M sum |M|^2 + lam sum |w o rbar|^2 / A."""
    normals = vertex_normals(body.vertices, body.faces)
    idx = np.flatnonzero(field.contact)
    frames = tangent_frames(normals[idx])
    w = local_reaction_weights(frames, field.params["mu"])
    rbar = np.einsum("kdi,kd->ki", frames, field.force[idx])
    react = ((w * rbar) ** 2).sum(axis=1) / field.area[idx]
    if np.isinf(lam):
        return react.sum()
    return 2.0 * (field.joint_moment**2).sum() + lam * react.sum()


def test_reactions_carry_the_weight(body, field):
    weight = body.segment_mass.sum() * GRAVITY
    total = field.force.sum(axis=0)
    assert abs(total[1] - weight) / weight < 1e-6
    assert np.abs(total[[0, 2]]).max() / weight < 1e-6


@pytest.mark.parametrize("point", [(0.0, 0.0, 0.0), (1.3, -2.0, 0.7), (-5.0, 3.0, 11.0)])
def test_net_moment_vanishes_about_any_point(body, field, point):
    p = np.asarray(point)
    gravity = np.zeros((N_SEGMENTS, 3))
    gravity[:, 1] = -GRAVITY * body.segment_mass
    moment = np.cross(body.vertices - p, field.force).sum(axis=0) + np.cross(body.segment_com - p, gravity).sum(axis=0)
    assert np.linalg.norm(moment) < 1e-7 * body.segment_mass.sum() * GRAVITY


def test_action_equals_reaction_at_every_joint(body, field):
    """The force at each joint from the child's side balances the one from the parent's side.

    Child side: balance of the subtree below the joint. Parent side: balance
    of everything else. Each is computed here from the reactions and gravity
    alone; the two must be equal and opposite, and equal to the reported one.
    """
    S = subtree_matrix()
    gravity = np.zeros((N_SEGMENTS, 3))
    gravity[:, 1] = -GRAVITY * body.segment_mass
    seg_ext = body.weights.T @ field.force + gravity  # external force on each segment
    seg_mom = body.weights.T @ np.cross(body.vertices, field.force) + np.cross(body.segment_com, gravity)
    for j in range(N_SEGMENTS - 1):
        below = S[:, j] > 0
        J = body.joints[j + 1]
        on_child = -seg_ext[below].sum(axis=0)  # what the parent must give the child
        on_parent = -seg_ext[~below].sum(axis=0)  # what the child must give the parent
        np.testing.assert_allclose(on_child + on_parent, 0.0, atol=1e-7)
        np.testing.assert_allclose(field.joint_force[j], on_child, atol=1e-7)
        m_child = -(seg_mom[below].sum(axis=0) - np.cross(J, seg_ext[below].sum(axis=0)))
        m_parent = -(seg_mom[~below].sum(axis=0) - np.cross(J, seg_ext[~below].sum(axis=0)))
        np.testing.assert_allclose(m_child + m_parent, 0.0, atol=1e-7)
        np.testing.assert_allclose(field.joint_moment[j], m_child, atol=1e-7)


def test_every_segment_is_in_equilibrium(body, field):
    assert field.residuals["segment_force"] < 1e-7
    assert field.residuals["segment_moment"] < 1e-7


def test_normal_forces_push_and_friction_pyramid_holds(body, field):
    normals = vertex_normals(body.vertices, body.faces)
    frames = tangent_frames(normals)
    rbar = np.einsum("ndi,nd->ni", frames, field.force)
    assert rbar[:, 0].min() >= -1e-9
    mu = field.params["mu"]
    assert (np.abs(rbar[:, 1:]) - mu * rbar[:, 0:1]).max() <= 1e-9
    # pressure is the normal force over the area
    np.testing.assert_allclose(field.pressure * field.area, field.normal_force, atol=1e-12)


def test_newton_agrees_with_piqp_on_the_paper_formulation(body, field):
    """PIQP solves the paper's unreduced QP (joint unknowns, 126 segment rows)."""
    ref = solve_pressure(body, exclude=[], backend="piqp")
    weight = body.segment_mass.sum() * GRAVITY
    assert np.abs(field.force - ref.force).max() < 1e-6 * weight
    np.testing.assert_allclose(field.joint_moment, ref.joint_moment, atol=1e-5)
    f_newton, f_piqp = _objective(body, field, 0.013), _objective(body, ref, 0.013)
    assert abs(f_newton - f_piqp) <= 1e-7 * abs(f_piqp)


def test_rigid_body_agrees_with_piqp(body):
    rigid = solve_pressure(body, exclude=[], lam=np.inf)
    ref = solve_pressure(body, exclude=[], lam=np.inf, backend="piqp")
    a, b = _objective(body, rigid, np.inf), _objective(body, ref, np.inf)
    assert a <= b * (1 + 1e-7)
    assert abs(a - b) <= 1e-6 * b


def test_the_exact_friction_cone_holds_balances_the_body_and_costs_no_less_than_the_pyramid(body, field):
    """The pyramid contains the circular cone, so the cone's optimum is never cheaper; no reaction leaves the cone."""
    cone = solve_pressure(body, exclude=[], friction="cone")
    weight = body.segment_mass.sum() * GRAVITY
    np.testing.assert_allclose(cone.force.sum(axis=0), [0, weight, 0], atol=1e-6 * weight)
    assert cone.residuals["segment_force"] < 1e-7 * weight and cone.residuals["segment_moment"] < 1e-7 * weight
    normals = vertex_normals(body.vertices, body.faces)
    rbar = np.einsum("ndi,nd->ni", tangent_frames(normals), cone.force)
    mu = cone.params["mu"]
    assert (np.linalg.norm(rbar[:, 1:], axis=1) - mu * rbar[:, 0]).max() <= 1e-9
    # the pyramid's optimum lies outside the circular cone at its corners
    rbar_p = np.einsum("ndi,nd->ni", tangent_frames(normals), field.force)
    assert (np.linalg.norm(rbar_p[:, 1:], axis=1) > mu * rbar_p[:, 0] * (1 + 1e-3)).any()
    pyramid_cost, cone_cost = _objective(body, field, 0.013), _objective(body, cone, 0.013)
    assert cone_cost >= pyramid_cost * (1 - 1e-6)
    with pytest.raises(InputError):
        solve_pressure(body, friction="octagon")


def test_moment_term_matters():
    """A smaller lambda lowers the joint moments (the paper's Pareto balance)."""
    body = seated_capsule_body(resolution=1)
    soft = solve_pressure(body, exclude=[], lam=1e-5)
    stiff = solve_pressure(body, exclude=[], lam=np.inf)
    assert (soft.joint_moment**2).sum() < 0.5 * (stiff.joint_moment**2).sum()


def _plate_body(com_xz, n=(41, 21), size=(1.0, 0.5)):
    """A flat rectangular plate at y = 0 facing down, all weight on one segment."""
    nx, nz = n
    xs = np.linspace(-size[0] / 2, size[0] / 2, nx)
    zs = np.linspace(-size[1] / 2, size[1] / 2, nz)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    verts = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], axis=1)
    idx = np.arange(nx * nz).reshape(nx, nz)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    # counter-clockwise seen from below (outward = -Y)
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    weights = np.zeros((len(verts), N_SEGMENTS))
    weights[:, 0] = 1.0
    mass = np.zeros(N_SEGMENTS)
    mass[0] = 60.0
    com = np.zeros((N_SEGMENTS, 3))
    com[:] = (com_xz[0], 0.3, com_xz[1])
    joints = np.zeros((N_SEGMENTS, 3))
    joints[:, 1] = 0.3
    return Body(verts, faces, weights, joints, joints + [0, 0.1, 0], mass, com, name="plate"), xs[1] - xs[0], zs[1] - zs[0]


def test_rigid_body_on_a_floor_is_penalty_contact():
    """lambda = inf on a flat floor: the pressure is clipped affine in floor coordinates.

    Independent computation: rigid penalty contact p = max(0, a + b x + c z)
    with the three unknowns fixed by the body's weight and the position of
    its centre of mass, solved here by an active-set iteration; grid areas
    h_x h_z (halved on edges, quartered at corners).
    """
    com_xz = (0.3, 0.05)  # far enough off-centre for part of the plate to lift
    body, hx, hz = _plate_body(com_xz)
    field = solve_pressure(body, exclude=[], lam=np.inf, mu=0.5)
    x, z = body.vertices[:, 0], body.vertices[:, 2]
    edge_x = np.isclose(np.abs(x), x.max())
    edge_z = np.isclose(np.abs(z), z.max())
    area = hx * hz * np.where(edge_x, 0.5, 1.0) * np.where(edge_z, 0.5, 1.0)
    weight = 60.0 * GRAVITY

    # active-set iteration on the piecewise-linear system: with the loaded
    # set fixed, weight and centre of mass are linear in (a, b, c)
    basis = np.stack([np.ones_like(x), x, z], axis=1)
    target = weight * np.array([1.0, com_xz[0], com_xz[1]])
    loaded = np.ones(len(x), bool)
    for _ in range(100):
        m = (basis[loaded] * area[loaded, None]).T @ basis[loaded]
        sol = np.linalg.solve(m, target)
        new_loaded = basis @ sol > 0
        if np.array_equal(new_loaded, loaded):
            break
        loaded = new_loaded
    expected = np.maximum(0.0, sol[0] + sol[1] * x + sol[2] * z)
    assert (expected == 0).sum() > 0.2 * len(x)  # the clipping is exercised
    assert np.abs(field.pressure - expected).max() <= 0.01 * expected.max()
    assert np.abs(field.pressure - expected).max() <= 1e-6 * expected.max()  # in fact exact
    np.testing.assert_allclose(field.area, area, rtol=1e-9)
    assert np.abs(field.force[:, [0, 2]]).max() < 1e-6  # no friction needed


def test_empty_contact_set_is_refused(body):
    with pytest.raises(InfeasibleSupportError, match="empty"):
        solve_pressure(body, contact=np.zeros(len(body.vertices), bool))


def test_head_only_support_is_refused(body):
    head = body.weights[:, 12] > 0.5
    with pytest.raises(InfeasibleSupportError, match="cannot hold the pose.*missing support under: Hips"):
        solve_pressure(body, contact=head)


def test_support_that_cannot_balance_the_moment_is_refused(body):
    """The soles alone: the centre of mass is behind the feet, no equilibrium exists."""
    soles = body.vertices[:, 1] < 0.01
    with pytest.raises(InfeasibleSupportError, match="cannot hold the body in equilibrium"):
        solve_pressure(body, contact=soles)


def test_contact_mask_is_respected(body):
    contact = body.vertices[:, 1] < 0.5
    field = solve_pressure(body, contact=contact, exclude=[])
    assert np.abs(field.force[~contact]).max() == 0.0
    assert not field.contact[~contact].any()


def test_bad_inputs_are_reported(body):
    with pytest.raises(InputError, match="contact must be"):
        solve_pressure(body, contact=np.ones(3, bool))
    for lam in (0.0, 1e308, float("nan")):
        with pytest.raises(InputError, match=r"lambda must be from 1e-09 to 1e\+06 \(or inf for a rigid body\)"):
            solve_pressure(body, lam=lam)
    for mu in (-0.1, float("inf"), float("nan")):  # --mu inf was a ValueError inside the QP
        with pytest.raises(InputError, match="mu must be from 0 to 10"):
            solve_pressure(body, mu=mu)
    with pytest.raises(RecipeError, match=r"^pressure.options.bogus: pressure solver 'qp' has no option 'bogus'; its options are: backend, friction, tol, weight_cap$"):
        QPPressureSolver().solve(body, options={"bogus": 1})
    with pytest.raises(RecipeError, match=r"pressure.options.backend: expected one of auto, newton, piqp, clarabel, got 'pqip'; did you mean 'piqp'\?"):
        QPPressureSolver().solve(body, options={"backend": "pqip"})


def test_mixed_voronoi_areas_sum_to_the_surface():
    v, f, _ = capsule((0, 0, 0), (0, 0.4, 0), 0.1, sectors=20, rings=6, stacks=5)
    areas = mixed_voronoi_areas(v, f)
    tri = v[f]
    total = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    assert areas.min() > 0
    assert abs(areas.sum() - total) < 1e-12 * total


def test_local_weights_follow_eqs_2_3():
    mu = 0.5
    # outward normals: straight down (seat), 45 degrees down-forward, sideways, up
    out = np.array([[0, -1, 0], [0, -np.sqrt(0.5), np.sqrt(0.5)], [1, 0, 0], [0, 1, 0]], float)
    frames = tangent_frames(out)
    w = local_reaction_weights(frames, mu)
    np.testing.assert_allclose(w[0], [1, 1, 1])
    c = np.sqrt(0.5)  # normal and downhill parts of the unit load on the slope
    r_t = min(c, mu * c)
    np.testing.assert_allclose(w[1], [1 / np.hypot(c, r_t), 1 / np.hypot(c, r_t), 1 / c])
    np.testing.assert_allclose(w[2], DEFAULT_WEIGHT_CAP)
    np.testing.assert_allclose(w[3], DEFAULT_WEIGHT_CAP)
    # frames are right-handed orthonormal, first column the inward normal
    np.testing.assert_allclose(np.einsum("kji,kjl->kil", frames, frames), np.broadcast_to(np.eye(3), (4, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(frames), 1.0)
    np.testing.assert_allclose(frames[:, :, 0], -out)


def test_contact_from_surface_finds_the_seat(body):
    # a seat rectangle at y = 0.43 under buttocks and thighs, as a 2-triangle mesh
    verts = np.array([[-0.3, 0.43, -0.3], [0.3, 0.43, -0.3], [0.3, 0.43, 0.45], [-0.3, 0.43, 0.45]])
    faces = np.array([[0, 2, 1], [0, 3, 2]])
    contact = contact_from_surface(body, (verts, faces), 0.01)
    plane_dist = np.abs(body.vertices[:, 1] - 0.43)
    inside = (np.abs(body.vertices[:, 0]) <= 0.3) & (body.vertices[:, 2] >= -0.3) & (body.vertices[:, 2] <= 0.45)
    assert contact[inside & (plane_dist <= 0.01)].all()
    assert not contact[plane_dist > 0.0125 + 1e-9].any()
    field = solve_pressure(body, contact=contact | (body.vertices[:, 1] < 0.01), exclude=[])
    assert field.force[contact, 1].sum() > 0.5 * body.segment_mass.sum() * GRAVITY


def test_subtree_matrix_follows_the_skeleton():
    S = subtree_matrix()
    for j in range(N_SEGMENTS - 1):
        for s in range(N_SEGMENTS):
            # s is below joint j iff walking up from s reaches segment j + 1
            a, below = s, False
            while a >= 0:
                below |= a == j + 1
                a = PARENTS[a]
            assert S[s, j] == float(below)
