"""Invariants of the Catmull-Clark operators, the cage checks, limit_surface."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from seatkit.errors import InputError
from seatkit.model import ControlMesh, Surface
from seatkit.subdivision import Cage, build_operators, limit_surface

_spec = importlib.util.spec_from_file_location(
    "seatkit_tests_osd_fixtures", Path(__file__).parent / "osd_reference" / "fixtures.py"
)
_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_fixtures)
runner = _fixtures.load_runner()


def _grid_cage(nx=4, nz=3, **kw):
    v, f = runner.grid(nx, nz)
    return Cage(v, np.array(f), **kw)


@pytest.mark.parametrize("case", runner.reference_cases()[:8], ids=lambda c: c.name)
@pytest.mark.parametrize("level", [1, 2, 3])
def test_operators_are_affine_and_shaped(case, level):
    cage = case.cage()
    ops = build_operators(cage, level)
    n = ops.refine.shape[0]
    for m in (ops.refine, ops.limit, ops.du, ops.dv):
        assert sp.isspmatrix_csr(m) or isinstance(m, sp.csr_array)
        assert m.shape == (n, cage.n_vertices)
    # Affine invariance: position masks sum to 1, tangent masks to 0.
    np.testing.assert_allclose(np.asarray(ops.refine.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(ops.limit.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(ops.du.sum(axis=1)).ravel(), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(ops.dv.sum(axis=1)).ravel(), 0.0, atol=1e-12)
    # Every refined face is a quad of valid indices; each face count is the
    # number of face corners of the previous level.
    assert ops.faces.shape[1] == 4 and ops.faces.dtype == np.int64
    assert ops.faces.min() >= 0 and ops.faces.max() < n
    assert len(ops.faces) == int(cage.face_sizes.sum()) * 4 ** (level - 1)
    assert ops.face_origin.shape == (len(ops.faces),)
    assert set(np.unique(ops.face_origin)) == set(range(cage.n_faces))


def test_operators_are_cached_per_topology():
    a = _grid_cage()
    b = a.with_vertices(a.vertices + 1.0)
    assert build_operators(a, 2) is build_operators(b, 2)
    creased = _grid_cage(crease_edges=[[6, 7]], crease_sharpness=[2.0])
    assert build_operators(creased, 2) is not build_operators(a, 2)
    assert build_operators(a, 3) is not build_operators(a, 2)


@pytest.mark.parametrize("case", runner.reference_cases()[:8], ids=lambda c: c.name)
def test_a_finer_level_from_a_cached_coarser_one_is_the_same_to_the_bit(case):
    """Level k + 1 goes on from a cached level k: the operators are those refined from the cage."""
    from seatkit.subdivision import catmull_clark

    cage = case.cage()

    def cold(level):
        catmull_clark._OPS_CACHE.clear()
        catmull_clark._LEVEL_CACHE.clear()
        return build_operators(cage, level)

    for finer in (2, 3, 4):
        fresh = cold(finer)
        for coarser in range(1, finer):
            cold(coarser)
            on = build_operators(cage, finer)
            assert on is not fresh
            for name in ("refine", "limit", "du", "dv"):
                a, b = getattr(fresh, name), getattr(on, name)
                assert np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
                assert np.array_equal(a.data, b.data)
            assert len(on.steps) == finer
            for name in ("faces", "face_origin", "rules"):
                assert np.array_equal(getattr(fresh, name), getattr(on, name))


def test_translation_and_scaling_commute():
    cage = runner.reference_cases()[1].cage()  # the creased chair
    ops = build_operators(cage, 2)
    P = cage.vertices
    shift = np.array([0.3, -1.2, 2.0])
    np.testing.assert_allclose(ops.limit @ (2.0 * P + shift), 2.0 * (ops.limit @ P) + shift, atol=1e-12)


def test_normals_follow_face_winding():
    v, f = runner.grid(5, 5, bump=0.05)
    flat_up = Cage(v, np.array(f))
    surf = limit_surface(flat_up, level=2)
    assert isinstance(surf, Surface)
    np.testing.assert_allclose(np.linalg.norm(surf.normals, axis=1), 1.0, atol=1e-12)
    assert (surf.normals[:, 1] > 0.8).all()
    flipped = Cage(v, np.array(f)[:, ::-1])
    assert (limit_surface(flipped, level=2).normals[:, 1] < -0.8).all()


def test_closed_cube_normals_point_out():
    v, f = runner.cube_cage()
    surf = limit_surface(Cage(v, f), level=3)
    centre = surf.vertices.mean(axis=0)
    assert (np.einsum("ij,ij->i", surf.normals, surf.vertices - centre) > 0).all()


def test_limit_of_planar_cage_stays_in_plane():
    v, f = runner.grid(6, 4, seed=None)
    cage = Cage(v, np.array(f), crease_edges=[[8, 9], [9, 10]], crease_sharpness=[1.5, 1.5])
    surf = limit_surface(cage, level=3)
    np.testing.assert_allclose(surf.vertices[:, 1], 0.0, atol=1e-15)
    np.testing.assert_allclose(np.abs(surf.normals[:, 1]), 1.0, atol=1e-12)


def test_edge_and_corner_keeps_corners_edge_only_rounds_them():
    v, f = runner.grid(3, 3, seed=None)
    corner = runner.grid_index(3, 0, 0)
    eac = build_operators(Cage(v, np.array(f)), 2)
    eo = build_operators(Cage(v, np.array(f), boundary="edge-only"), 2)
    np.testing.assert_allclose((eac.limit @ v)[corner], v[corner], atol=1e-15)
    assert np.linalg.norm((eo.limit @ v)[corner] - v[corner]) > 0.1


def test_sharp_crease_is_a_curve_of_the_cage():
    """An infinitely sharp interior crease line: the limit passes through the
    B-spline curve of the crease polygon (a straight line here)."""
    v, f = runner.grid(6, 6, seed=None)
    v[:, 1] = np.where(v[:, 2] == 3, 1.0, 0.0)  # a ridge along row z = 3
    row = [(runner.grid_index(6, 3, j), runner.grid_index(6, 3, j + 1)) for j in range(6)]
    sharp = limit_surface(Cage(v, np.array(f), crease_edges=row), level=3)
    smooth = limit_surface(Cage(v, np.array(f)), level=3)
    on_ridge = np.isclose(sharp.vertices[:, 2], 3.0)
    assert on_ridge.sum() > 10
    np.testing.assert_allclose(sharp.vertices[on_ridge, 1], 1.0, atol=1e-12)
    assert smooth.vertices[np.isclose(smooth.vertices[:, 2], 3.0), 1].max() < 0.8


def test_semi_sharp_lies_between_smooth_and_sharp():
    v, f = runner.grid(6, 6, seed=None)
    v[:, 1] = np.where(v[:, 2] == 3, 1.0, 0.0)
    row = [(runner.grid_index(6, 3, j), runner.grid_index(6, 3, j + 1)) for j in range(6)]
    centre = runner.grid_index(6, 3, 3)
    heights = []
    for s in (0.0, 0.5, 1.0, 2.3, 10.0):
        cage = Cage(v, np.array(f), crease_edges=row, crease_sharpness=[s] * 6)
        heights.append((build_operators(cage, 4).limit @ v)[centre, 1])
    assert np.all(np.diff(heights) > 0), heights
    assert heights[-1] == pytest.approx(1.0, abs=1e-12)


def test_from_control_mesh_and_limit_surface():
    v, f = runner.grid(3, 2)
    cm = ControlMesh(
        vertices=v,
        faces=np.array(f),
        face_segments=np.arange(6),
        crease_edges=np.array([[0, 1]]),
        crease_sharpness=np.array([3.0]),
        corners=np.array([5]),
        corner_sharpness=np.array([1.0]),
    )
    cage = Cage.from_control_mesh(cm)
    assert cage.crease_sharpness.dtype == np.float32
    assert cage.corners.tolist() == [5]
    surf = limit_surface(cm, level=2)
    ops = build_operators(cage, 2)
    np.testing.assert_allclose(surf.vertices, ops.limit @ v)
    assert surf.faces.shape == (6 * 16, 4) and surf.level == 2


def test_level_zero_needs_quads_and_is_identity():
    cage = _grid_cage()
    ops = build_operators(cage, 0)
    np.testing.assert_allclose(ops.refine.toarray(), np.eye(cage.n_vertices))
    np.testing.assert_array_equal(ops.faces, cage.faces)
    tri = Cage(np.eye(3), [[0, 1, 2]])
    with pytest.raises(InputError, match="level 0"):
        build_operators(tri, 0)
    with pytest.raises(InputError, match="non-negative integer"):
        build_operators(cage, -1)


# ----------------------------------------------------------------------------- bad cages

QUAD = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1.0]])


def test_non_manifold_edge():
    v = np.vstack([QUAD, [[0.5, 1, 0.5], [0.5, -1, 0.5]]])
    faces = [[0, 1, 4], [1, 0, 5], [0, 1, 2, 3]]
    with pytest.raises(InputError, match="shared by 3 faces.*non-manifold"):
        Cage(v, faces)


def test_inconsistent_winding():
    v = np.vstack([QUAD, [[2, 0, 0], [2, 0, 1]]])
    with pytest.raises(InputError, match="windings disagree"):
        Cage(v, [[0, 3, 2, 1], [2, 1, 4, 5]])


def test_non_manifold_vertex():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1], [-1, 0, 0], [0, 0, -1.0]])
    with pytest.raises(InputError, match="vertex 0 is non-manifold"):
        Cage(v, [[0, 2, 1], [0, 4, 3]])


def test_small_face():
    with pytest.raises(InputError, match="face 1 has 2 vertices"):
        Cage(QUAD, [[0, 3, 2, 1], [0, 1]])


def test_index_out_of_range():
    with pytest.raises(InputError, match="face 0 refers to vertex 7, out of range for 4"):
        Cage(QUAD, [[0, 3, 2, 7]])


def test_nan_coordinates():
    v = QUAD.copy()
    v[2, 1] = np.nan
    with pytest.raises(InputError, match="vertex 2 has non-finite"):
        Cage(v, [[0, 3, 2, 1]])


def test_crease_on_missing_edge():
    with pytest.raises(InputError, match=r"crease 1 names edge \(0, 2\), which is not an edge"):
        Cage(QUAD, [[0, 3, 2, 1]], crease_edges=[[0, 1], [0, 2]], crease_sharpness=[1.0, 2.0])


def test_repeated_vertex_unused_vertex_bad_sharpness_bad_mode():
    with pytest.raises(InputError, match="uses vertex 1 more than once"):
        Cage(QUAD, [[0, 1, 2, 1]])
    with pytest.raises(InputError, match="vertex 3 is not used"):
        Cage(QUAD, [[0, 2, 1]])
    with pytest.raises(InputError, match="crease_sharpness must be >= 0"):
        Cage(QUAD, [[0, 3, 2, 1]], crease_edges=[[0, 1]], crease_sharpness=[-1.0])
    with pytest.raises(InputError, match="boundary must be one of"):
        Cage(QUAD, [[0, 3, 2, 1]], boundary="none")
    with pytest.raises(InputError, match="corner vertex 9 is out of range"):
        Cage(QUAD, [[0, 3, 2, 1]], corners=[9])
