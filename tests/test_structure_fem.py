"""The shell FEM against closed forms (docs/structure.md, "Validation").

Each model is meshed at the analysis' default resolution: quadratic
hexahedra, one through the thickness (:data:`DEFAULT_LAYERS`), and as many
across a span as the default chair has across its seat (8, see
docs/structure.md).
"""

import numpy as np
import pytest
import skfem
from skfem.models.elasticity import lame_parameters, linear_elasticity

from seatkit.structure.analysis import DEFAULT_LAYERS
from seatkit.structure.fem import Elasticity
from seatkit.structure.loads import TopQuadrature
from seatkit.structure.materials import MATERIALS, Material
from seatkit.structure.mesh import ShellMesh, plate_quads9

#: Elements across a span at the default resolution.
SPAN_ELEMENTS = 8

STEEL = MATERIALS["steel"]
NU03 = Material("test", 200e9, 0.3, 250e6, 7850.0, "", "")


def _plate(nx, ny, a, b, t, material=NU03, layers=DEFAULT_LAYERS):
    V, N, q9 = plate_quads9(nx, ny, a, b)
    mesh = ShellMesh.extrude(V, N, q9, t, layers)
    return mesh, Elasticity(mesh, material)


def _pressure(mesh, q):
    """Nodal forces of a uniform pressure q (Pa) pushing down on the top face."""
    quad = TopQuadrature(mesh)
    force = np.zeros((len(quad.points), 3))
    force[:, 1] = -q * quad.weights
    return quad.nodal(force, len(mesh.nodes))


def _clamped_plate(t, a=1.0, q=1000.0):
    mesh, model = _plate(SPAN_ELEMENTS, SPAN_ELEMENTS, a, a, t)
    x, z = mesh.nodes[:, 0], mesh.nodes[:, 2]
    edge = np.flatnonzero((x < 1e-9) | (x > a - 1e-9) | (z < 1e-9) | (z > a - 1e-9))
    sol = model.solve(_pressure(mesh, q), edge)
    centre = np.flatnonzero(np.linalg.norm(mesh.nodes - [a / 2, -t / 2, a / 2], axis=1) < 1e-9)
    return mesh, sol, centre


def _interior_stress(mesh, sol, a=1.0):
    """Largest von Mises stress of the elements that do not touch the clamped edge (its corners are singular)."""
    centre = mesh.nodes[mesh.elements].mean(axis=0)  # (E, 3)
    h = a / SPAN_ELEMENTS
    inner = (np.abs(centre[:, [0, 2]] - a / 2) < a / 2 - h).all(axis=1)
    return sol.von_mises[inner].max()


def test_stiffness_matches_scikit_fem_assembly():
    """The bulk assembly equals skfem.asm(linear_elasticity) entry by entry (a curved, distorted mesh)."""
    V, N, q9 = plate_quads9(2, 1, 0.3, 0.2)
    V = V + np.c_[0.02 * np.sin(7 * V[:, 2]), 0.1 * V[:, 0] ** 2, 0.01 * V[:, 0]]  # curved and skewed
    mesh = ShellMesh.extrude(V, N, q9, 0.03, layers=2)
    model = Elasticity(mesh, NU03, assumed_strain=False)
    vector = skfem.Basis(mesh.skfem_mesh(), skfem.ElementVector(skfem.ElementHex2()), intorder=4)
    reference = skfem.asm(linear_elasticity(*lame_parameters(NU03.youngs_modulus_pa, NU03.poisson_ratio)), vector)
    scalar = model.element_dofs
    perm = np.empty(model.n_dofs, np.int64)
    for a in range(scalar.shape[0]):  # ElementVector interleaves the components of each scalar dof
        for c in range(3):
            perm[3 * scalar[a] + c] = vector.element_dofs[3 * a + c]
    diff = abs(reference[perm][:, perm] - model.stiffness).max()
    assert diff <= 1e-12 * abs(reference).max()


@pytest.mark.parametrize("shape", [(1, 1, 1), (3, 2, 1), (2, 2, 2)])
def test_assumed_strain_stiffness_has_only_the_rigid_motions_as_zero_modes(shape):
    """The MITC9 assumed strains bring no spurious zero-energy (hourglass) mode, even in one element."""
    nx, ny, layers = shape
    V, N, q9 = plate_quads9(nx, ny, 0.4, 0.3)
    V = V + np.c_[0 * V[:, 0], 0.3 * V[:, 0] ** 2 + 0.2 * V[:, 2] ** 2, 0.05 * V[:, 2]]  # doubly curved
    model = Elasticity(ShellMesh.extrude(V, N, q9, 0.01, layers), NU03)
    eig = np.linalg.eigvalsh(model.stiffness.toarray())
    assert (eig < 1e-10 * eig.max()).sum() == 6
    assert eig.min() > -1e-10 * eig.max()


def test_clamped_square_plate_matches_timoshenko():
    """w_max = 0.00126 q a^4 / D (Timoshenko & Woinowsky-Krieger 1959, section 44; nu = 0.3) within 3%."""
    a, t, q = 1.0, 0.01, 1000.0
    mesh, sol, centre = _clamped_plate(t, a, q)
    D = NU03.youngs_modulus_pa * t**3 / (12 * (1 - NU03.poisson_ratio**2))
    expected = 0.00126 * q * a**4 / D
    w = -sol.displacement[centre, 1].item()
    assert w == pytest.approx(expected, rel=0.03)
    assert np.abs(sol.displacement[:, 1]).max() == pytest.approx(w, rel=1e-3)  # the centre deflects most


def test_clamped_square_plate_stress_matches_timoshenko():
    """The surface stress at the centre, 6 M / t^2 with M = 0.0231 q a^2 (ibid., nu = 0.3), within 5%.

    Equal bending moments both ways: von Mises equals either stress. The
    largest interior stress is at the centre (read at the element's Barlow
    points beside it, a/38 away, where the moment is a little lower).
    """
    a, t, q = 1.0, 0.01, 1000.0
    mesh, sol, _ = _clamped_plate(t, a, q)
    assert _interior_stress(mesh, sol, a) == pytest.approx(6 * 0.0231 * q * a**2 / t**2, rel=0.05)


def test_cantilever_strip_matches_beam_theory():
    """Tip deflection P L^3 / (3 E I) within 3%, and the root stress 6 P L / (b t^2) within 10% of it."""
    L, b, t, P = 1.0, 0.02, 0.01, 10.0
    mesh, model = _plate(1, SPAN_ELEMENTS, b, L, t)  # x across the width, z along the length
    z = mesh.nodes[:, 2]
    root = np.flatnonzero(z < 1e-9)
    tip = np.flatnonzero(z > L - 1e-9)
    # a uniform shear traction on the end face: consistent weights [1, 4, 1] / 6 per direction
    w1 = np.array([1.0, 4.0, 1.0]) / 6.0
    x_rank = np.rint(mesh.nodes[tip, 0] / (b / 2)).astype(int)
    y_rank = np.rint((mesh.nodes[tip, 1] + t) / (t / 2)).astype(int)
    load = np.zeros((len(mesh.nodes), 3))
    load[tip, 1] = -P * w1[x_rank] * w1[y_rank]
    assert load[:, 1].sum() == pytest.approx(-P)
    sol = model.solve(load, root)
    EI = NU03.youngs_modulus_pa * b * t**3 / 12
    mid = tip[(x_rank == 1) & (y_rank == 1)]
    assert -sol.displacement[mid, 1].item() == pytest.approx(P * L**3 / (3 * EI), rel=0.03)


def test_floor_reaction_equals_applied_load():
    mesh, sol, _ = _clamped_plate(0.02)
    applied = sol.load.sum(axis=0)
    assert np.abs(sol.reaction.sum(axis=0) + applied).max() <= 1e-6 * np.abs(applied).max()


def test_thin_plate_scales_as_t_cubed_and_t_squared():
    """Halving a thin plate's thickness: deflection x 8 (t^-3), stress x 4 (t^-2), within 10%.

    The stress is the largest away from the clamped edge: at the clamp's
    corners the 3-D solution is singular and its value depends on the mesh.
    """
    out = {}
    for t in (0.01, 0.005):
        mesh, sol, centre = _clamped_plate(t)
        out[t] = (-sol.displacement[centre, 1].item(), _interior_stress(mesh, sol))
    (w1, s1), (w2, s2) = out[0.01], out[0.005]
    assert w2 / w1 == pytest.approx(8.0, rel=0.10)
    assert s2 / s1 == pytest.approx(4.0, rel=0.10)


def test_a_shell_held_nowhere_is_one_clear_error():
    from seatkit.structure import StructureError

    mesh, model = _plate(2, 2, 1.0, 1.0, 0.01)
    with pytest.raises(StructureError, match="nothing holds it"):
        model.solve(_pressure(mesh, 100.0), np.zeros(0, np.int64))


@pytest.mark.parametrize("solver", ["cholmod", "superlu"])
@pytest.mark.parametrize("layers", [1, 2])
def test_condensed_solve_equals_the_global_solve(layers, solver, monkeypatch):
    """Eliminating each element's own nodes first (held ones among them) changes nothing but rounding.

    A curved plate held on one edge and on its whole underside near it (the
    bottom-face centre nodes there are held: with one layer they belong to
    one element only) under a uniform pressure, against a direct solve of
    the global stiffness with the held rows and columns taken out; with
    either factorisation of the condensed stiffness.
    """
    import scipy.sparse.linalg as sla

    from seatkit.structure import solvers

    if solver == "cholmod":
        pytest.importorskip("cvxopt")
    monkeypatch.setattr(solvers, "SOLVER", solver)
    V, N, q9 = plate_quads9(3, 4, 0.3, 0.4)
    V = V + np.c_[0 * V[:, 0], 0.2 * V[:, 0] ** 2 + 0.1 * V[:, 2] ** 2, 0 * V[:, 0]]
    mesh = ShellMesh.extrude(V, N, q9, 0.01, layers)
    model = Elasticity(mesh, NU03)
    z = mesh.nodes[:, 2]
    held_nodes = np.union1d(np.flatnonzero(z < 1e-9), mesh.bottom[z[mesh.bottom] < 0.11])
    load = _pressure(mesh, 1000.0)
    load[:, 0] += 0.3 * load[:, 1]  # a friction-like shear too
    sol = model.solve(load, held_nodes)
    assert sol.solver.lower().startswith(solver)
    f = np.zeros(model.n_dofs)
    f.reshape(-1, 3)[model.dof] = load
    held = np.zeros(model.n_dofs, bool)
    held.reshape(-1, 3)[model.dof[held_nodes]] = True
    free = np.flatnonzero(~held)
    u = np.zeros(model.n_dofs)
    u[free] = sla.spsolve(model.stiffness[free][:, free].tocsc(), f[free])
    expected = u.reshape(-1, 3)[model.dof]
    assert np.abs(sol.displacement - expected).max() <= 1e-8 * np.abs(expected).max()  # rounding: the stiffness is ill-conditioned (thin)
    reaction = (model.stiffness @ u - f).reshape(-1, 3)[model.dof]
    reaction[np.setdiff1d(np.arange(len(mesh.nodes)), held_nodes)] = 0.0
    assert np.abs(sol.reaction - reaction).max() <= 1e-8 * np.abs(reaction).max()


def test_without_cvxopt_the_analysis_falls_back_to_superlu(monkeypatch):
    """cvxopt (CHOLMOD) is an optional accelerator: where it does not import, SuperLU solves, to the same answer."""
    import sys

    from seatkit.structure import solvers

    pytest.importorskip("cvxopt")
    t = 0.01
    _, with_cholmod, _ = _clamped_plate(t)
    monkeypatch.setitem(sys.modules, "cvxopt", None)  # import cvxopt now raises ImportError
    assert solvers.SOLVER == "auto" and solvers.factorise_name() == "SuperLU (scipy)"
    _, without, _ = _clamped_plate(t)
    assert with_cholmod.solver == "CHOLMOD (cvxopt)" and without.solver == "SuperLU (scipy)"
    scale = np.abs(without.displacement).max()
    assert np.abs(with_cholmod.displacement - without.displacement).max() <= 1e-9 * scale
    assert np.abs(with_cholmod.von_mises - without.von_mises).max() <= 1e-9 * without.von_mises.max()


def _scordelis_lo_roof(n, assumed_strain=True):
    """Vertical deflection at the middle of a free edge of the Scordelis-Lo roof, n x n elements.

    A cylindrical panel (radius 25 to its mid-surface, length 50, 80 degrees
    wide, thickness 0.25, E = 4.32e8, nu = 0) under its own weight, 90 per
    unit area, on rigid diaphragms at its curved ends (held across, free
    along the axis), its straight edges free: the membrane-locking benchmark
    of MacNeal & Harder (Finite Elements in Analysis and Design 1, 1985),
    reference 0.3024.
    """
    import scipy.sparse.linalg as sla

    from seatkit.structure.fem import GRAVITY

    R, L, t = 25.0, 50.0, 0.25
    V, _, q9 = plate_quads9(n, n, 1.0, L)
    angle = np.radians(-40.0 + 80.0 * V[:, 0])
    normal = np.c_[np.sin(angle), np.cos(angle), 0 * angle]
    top = np.c_[(R + t / 2) * normal[:, :2], V[:, 2]]
    mesh = ShellMesh.extrude(top, normal, q9, t, DEFAULT_LAYERS)
    model = Elasticity(mesh, Material("roof", 4.32e8, 0.0, 1e9, 90.0 / (t * GRAVITY), "", ""), assumed_strain=assumed_strain)
    f = np.zeros(model.n_dofs)
    f.reshape(-1, 3)[model.dof] = model.weight_load()
    z = mesh.nodes[:, 2]
    ends = model.dof[np.flatnonzero((z < 1e-9) | (z > L - 1e-9))]
    held = np.zeros((model.n_dofs // 3, 3), bool)
    held[ends, :2] = True
    free = np.flatnonzero(~held.ravel())
    u = np.zeros(model.n_dofs)
    u[free] = sla.spsolve(model.stiffness[free][:, free].tocsc(), f[free])
    mid = mesh.n_surface + np.flatnonzero((V[:, 0] < 1e-9) & (np.abs(V[:, 2] - L / 2) < 1e-9))  # mid-surface sheet
    return -u.reshape(-1, 3)[model.dof[mid], 1].item()


def test_thin_curved_shell_does_not_lock():
    """The Scordelis-Lo roof (R/t = 100) at 8 x 8 elements within 3% of 0.3024; fully integrated it locks."""
    assert _scordelis_lo_roof(SPAN_ELEMENTS) == pytest.approx(0.3024, rel=0.03)
    assert _scordelis_lo_roof(SPAN_ELEMENTS, assumed_strain=False) < 0.9 * 0.3024


def test_element_product_is_the_stiffness_times_u():
    """The stable element product (each element's rigid motion taken out first) is K u, to rounding."""
    V, N, q9 = plate_quads9(3, 2, 0.3, 0.2)
    V = V + np.c_[0.02 * np.sin(7 * V[:, 2]), 0.1 * V[:, 0] ** 2, 0.01 * V[:, 0]]  # curved and skewed
    mesh = ShellMesh.extrude(V, N, q9, 0.02)
    model = Elasticity(mesh, NU03)
    u = np.random.default_rng(1).standard_normal(model.n_dofs) * 1e-3
    expected = model.stiffness @ u
    assert np.abs(model._element_product(u) - expected).max() <= 1e-11 * np.abs(expected).max()
    # a rigid motion (a translation plus a rotation) has no internal force, element by element
    x = np.zeros((model.n_scalar, 3))
    x[model.dof] = mesh.nodes
    rigid = (np.array([1e-3, -2e-3, 5e-4]) + np.cross([0.01, -0.02, 0.03], x)).ravel()
    assert np.abs(model._element_product(rigid)).max() <= 1e-13 * abs(model.stiffness).max() * np.abs(rigid).max()


def _corrugated(amplitude, t=0.04, span=1.0, waves=4, nx=16):
    """A plate corrugated along x (y = A sin(2 pi waves x / span)), its shell offset below it by ``t``."""
    V, N, q9 = plate_quads9(nx, 2, span, 0.2)
    k = 2 * np.pi * waves / span
    V = V.copy()
    V[:, 1] = amplitude * np.sin(k * V[:, 0])
    slope = amplitude * k * np.cos(k * V[:, 0])
    N = np.stack([-slope, np.ones_like(slope), np.zeros_like(slope)], axis=1)
    N /= np.linalg.norm(N, axis=1)[:, None]
    mesh = ShellMesh.extrude(V, N, q9, t)
    return mesh, Elasticity(mesh, MATERIALS["birch-plywood"])


def test_a_nearly_singular_stiffness_is_refused_not_answered():
    """A shell folded exactly through itself has a nearly singular stiffness: one clear error, no wrong numbers.

    The corrugation's crests curl tighter as the amplitude grows; past the
    thickness the offset folds over itself. Bisecting the amplitude to where
    the mapping of the crest elements nearly vanishes at a quadrature point
    (smallest over largest determinant 1e-6) makes the stiffness nearly
    singular: the displacements SuperLU returns balance nothing, and the
    floor reaction, which must equal the load, shows it.
    """
    from seatkit.structure import StructureError

    lo, hi = 0.01, 0.08  # sound, folded
    assert _corrugated(lo)[1].det.min() > 0 > _corrugated(hi)[1].det.min()
    for _ in range(60):
        mesh, model = _corrugated(lo)
        if model.det.min() < 1e-6 * model.det.max():
            break
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _corrugated(mid)[1].det.min() > 0 else (lo, mid)
    assert model.det.min() < 1e-6 * model.det.max()
    x = mesh.nodes[:, 0]
    ends = np.flatnonzero((x < 1e-9) | (x > 1.0 - 1e-9))
    with pytest.raises(StructureError, match="floor reaction misses the applied load"):
        model.solve(_pressure(mesh, 2000.0) + model.weight_load(), ends)
    # a little less amplitude (the fold's mapping 1e-3 from vanishing) is solved, and balances
    mesh, model = _corrugated(0.0558)
    assert 0 < model.det.min() < 2e-3 * model.det.max()
    sol = model.solve(_pressure(mesh, 2000.0) + model.weight_load(), ends)
    applied = sol.load.sum(axis=0)
    assert np.abs(sol.reaction.sum(axis=0) + applied).max() <= 1e-6 * np.abs(applied).max()


def _pinched_plate(shift, t=0.01):
    """The clamped plate with one element's centre node moved ``shift`` along x: that element's mapping nearly vanishes."""
    V, N, q9 = plate_quads9(SPAN_ELEMENTS, SPAN_ELEMENTS, 1.0, 1.0)
    V[(2 * 3 + 1) * (2 * SPAN_ELEMENTS + 1) + (2 * 4 + 1), 0] += shift  # the surface centre of element (3, 4)
    mesh = ShellMesh.extrude(V, N, q9, t)
    x, z = mesh.nodes[:, 0], mesh.nodes[:, 2]
    edge = np.flatnonzero((x < 1e-9) | (x > 1.0 - 1e-9) | (z < 1e-9) | (z > 1.0 - 1e-9))
    return mesh, edge


def test_one_nearly_folded_element_among_sound_ones_is_capped_and_solved(monkeypatch):
    """A single element whose mapping all but vanishes is rigid to its neighbours: capped, the plate solves and balances.

    Its stiffness grows as the inverse cube of the vanishing determinant
    (millions of times a sound element's): uncapped, no displacement in
    double precision balances it and the solve is refused, as the default
    chair in 2 cm plywood was. Capped at STIFFNESS_CAP times a typical
    element (its eigenvalues on its deformations), the plate balances to
    1e-6, and the figures do not depend on the cap: rigid is rigid.
    """
    from seatkit.structure import StructureError, fem

    lo, hi = 0.0, 0.0625  # sound, folded
    assert Elasticity(_pinched_plate(hi)[0], NU03).det.min() < 0
    for _ in range(80):
        model = Elasticity(_pinched_plate(lo)[0], NU03)
        if model.det.min() < 1e-7 * model.det.max():
            break
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if Elasticity(_pinched_plate(mid)[0], NU03).det.min() > 0 else (lo, mid)
    mesh, edge = _pinched_plate(lo)
    figures = {}
    for cap in (np.inf, fem.STIFFNESS_CAP / 10, fem.STIFFNESS_CAP, fem.STIFFNESS_CAP * 10):
        monkeypatch.setattr(fem, "STIFFNESS_CAP", cap)
        model = Elasticity(mesh, NU03)
        assert 0 < model.det.min() < 1e-7 * model.det.max()
        load = _pressure(mesh, 1000.0) + model.weight_load()
        if cap == np.inf:
            with pytest.raises(StructureError, match="floor reaction misses the applied load"):
                model.solve(load, edge)
            continue
        sol = model.solve(load, edge)
        applied = sol.load.sum(axis=0)
        assert np.abs(sol.reaction.sum(axis=0) + applied).max() <= 1e-6 * np.abs(applied).max()
        figures[cap] = np.abs(sol.displacement).max(), sol.von_mises.max()
    deflection, stress = np.array(list(figures.values())).T
    assert np.ptp(deflection) <= 1e-6 * deflection.max() and np.ptp(stress) <= 1e-6 * stress.max()


def test_strains_of_u_equal_the_strain_rows_times_u():
    """The stresses' strains, from the tying-point strains of u directly, are the stiffness' strain rows times u."""
    V, N, q9 = plate_quads9(3, 2, 0.3, 0.2)
    V = V + np.c_[0.02 * np.sin(7 * V[:, 2]), 0.1 * V[:, 0] ** 2 + 0.2 * V[:, 2] ** 2, 0.01 * V[:, 0]]
    mesh = ShellMesh.extrude(V, N, q9, 0.02)
    model = Elasticity(mesh, NU03)
    u = np.random.default_rng(2).standard_normal(model.n_dofs) * 1e-3
    for points in (model.stress_points, model.full):
        rows = model.strain_rows(points, slice(None))  # (E, P, 6, 81)
        expected = np.einsum("epvx,ex->epv", rows, u[model._vector_dofs()])
        assert np.abs(model.strains(points, u) - expected).max() <= 1e-12 * np.abs(expected).max()
