"""The final check's broad phases find every crossing that an all-pairs test finds.

The cage-against-body and cage-against-itself checks
(:mod:`seatkit.template.checks`) test only candidate pairs found with k-d
trees; a candidate set that misses a crossing pair would pass a cage that
crosses the body. Here they are compared with the exact test run on every
pair, on a sphere crossed by a random cage, and the triangle cover the first
pass samples is checked to reach every point of its triangle; the clearance
step's grid keeps every body vertex within reach of the cage's samples, and
the fit's cross products and unit vectors are numpy's to the bit.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from seatkit.model import Body
from seatkit.template.clearance import _within_reach
from seatkit.template.planes import _neighbour_cut, cross, unit
from seatkit.template.checks import (
    _cover_triangles,
    crossing_faces,
    quad_triangles,
    segments_cross_triangles,
    self_intersecting_faces,
)


def _sphere_body(radius=0.2, centre=(0.0, 0.5, 0.0), subdivisions=3) -> Body:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    n = len(mesh.vertices)
    return Body(
        vertices=np.asarray(mesh.vertices) + centre,
        faces=np.asarray(mesh.faces, dtype=np.int64),
        weights=np.full((n, 21), 1 / 21),
        joints=np.zeros((21, 3)),
        tips=np.zeros((21, 3)),
        segment_mass=np.full(21, 75 / 21),
        segment_com=np.zeros((21, 3)),
    )


def _random_cage(rng, rows=5, cols=6, size=0.6, bump=0.15):
    """A wavy quad grid through the sphere's region (faces (r*c, 4))."""
    u, v = np.meshgrid(np.linspace(-size / 2, size / 2, cols + 1), np.linspace(0.5 - size / 2, 0.5 + size / 2, rows + 1))
    z = rng.normal(scale=bump, size=u.shape)
    V = np.stack([u, v, z], -1).reshape(-1, 3)
    ids = np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    Q = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], -1).reshape(-1, 4)
    return V, Q


def _brute_crossing(vertices, quads, body, tolerance):
    """crossing_faces by testing every body edge against every cage triangle and every cage edge against every body triangle."""
    V = np.asarray(vertices, float)
    Q = V[quads]
    fn = np.cross(Q[:, 2] - Q[:, 0], Q[:, 3] - Q[:, 1])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-12)
    Q = Q - tolerance * fn[:, None, :]
    points, tris, owner = quad_triangles(Q.reshape(-1, 3), np.arange(4 * len(quads)).reshape(-1, 4))
    bv, bf = body.vertices, body.faces
    edges = np.unique(np.sort(np.concatenate([bf[:, [0, 1]], bf[:, [1, 2]], bf[:, [2, 0]]]), 1), axis=0)
    bad = np.zeros(len(quads), bool)
    ti, ej = (a.ravel() for a in np.meshgrid(np.arange(len(tris)), np.arange(len(edges)), indexing="ij"))
    T = points[tris[ti]]
    hit = segments_cross_triangles(bv[edges[ej, 0]], bv[edges[ej, 1]], T[:, 0], T[:, 1], T[:, 2])
    bad[owner[ti[hit]]] = True
    cage_edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    eo = np.tile(owner, 3)
    ei, tj = (a.ravel() for a in np.meshgrid(np.arange(len(cage_edges)), np.arange(len(bf)), indexing="ij"))
    B = bv[bf[tj]]
    hit = segments_cross_triangles(points[cage_edges[ei, 0]], points[cage_edges[ei, 1]], B[:, 0], B[:, 1], B[:, 2])
    bad[eo[ei[hit]]] = True
    return np.flatnonzero(bad)


def test_crossing_faces_finds_what_every_pair_finds():
    body = _sphere_body(subdivisions=2)
    rng = np.random.default_rng(7)
    found = 0
    for _ in range(12):
        V, Q = _random_cage(rng)
        for tolerance in (0.0, 0.007):
            got = crossing_faces(V, Q, body, tolerance)
            want = _brute_crossing(V, Q, body, tolerance)
            np.testing.assert_array_equal(got, want)
            found += len(want)
    assert found > 0  # the cages do cross the sphere


def test_a_quad_crosses_the_body_whatever_the_rest_of_the_cage_and_a_moved_quad_is_tested_again():
    # the check keeps each quad's answer per body (a repair moves a few quads; the check runs again)
    body = _sphere_body(subdivisions=2)
    rng = np.random.default_rng(11)
    V, Q = _random_cage(rng)
    whole = crossing_faces(V, Q, body, 0.007)
    assert 0 < len(whole) < len(Q)
    for i in range(len(Q)):  # each quad alone, on a new body object (nothing kept for it)
        alone = crossing_faces(V, Q[i : i + 1], dataclasses.replace(body), 0.007)
        assert (len(alone) == 1) == (i in whole)
    moved = V.copy()
    moved[Q[whole[0]]] += rng.normal(scale=0.05, size=(4, 3))  # the corners of a crossing quad, and their neighbours' corners
    for tolerance in (0.007, 0.0):
        np.testing.assert_array_equal(crossing_faces(moved, Q, body, tolerance), _brute_crossing(moved, Q, body, tolerance))
    np.testing.assert_array_equal(crossing_faces(V, Q, body, 0.007), whole)


def test_self_intersections_match_every_pair():
    rng = np.random.default_rng(3)
    for _ in range(10):
        V, Q = _random_cage(rng, bump=0.3)
        got = self_intersecting_faces(V, Q)
        points, tris, owner = quad_triangles(V, Q)
        i, j = (a.ravel() for a in np.meshgrid(np.arange(len(tris)), np.arange(len(tris)), indexing="ij"))
        keep = owner[i] < owner[j]
        i, j = i[keep], j[keep]
        shared = (Q[owner[i]][:, :, None] == Q[owner[j]][:, None, :]).any((1, 2))
        i, j = i[~shared], j[~shared]
        hit = np.zeros(len(i), bool)
        for a_, b_ in ((i, j), (j, i)):
            T = points[tris[b_]]
            for e0, e1 in ((0, 1), (1, 2), (2, 0)):
                hit |= segments_cross_triangles(points[tris[a_, e0]], points[tris[a_, e1]], T[:, 0], T[:, 1], T[:, 2])
        want = np.unique(np.sort(np.stack([owner[i[hit]], owner[j[hit]]], 1), 1), axis=0).reshape(-1, 2)
        np.testing.assert_array_equal(got, want)


coords = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.tuples(coords, coords, coords), min_size=3, max_size=3),
    st.floats(0.0, 1.0),
    st.sampled_from([0.005, 0.03, 0.2]),
)
def test_triangle_cover_reaches_every_point(corners, squash, spacing):
    P = np.array(corners)
    # squash the third corner towards the first edge: long thin triangles too
    mid = 0.5 * (P[0] + P[1])
    P[2] = mid + squash * (P[2] - mid)
    samples, owner = _cover_triangles(P, np.array([[0, 1, 2]]), spacing)
    assert (owner == 0).all()
    u = np.random.default_rng(0).random((3000, 2))
    flip = u.sum(1) > 1
    u[flip] = 1 - u[flip]
    pts = np.vstack([P, P[0] + u[:, :1] * (P[1] - P[0]) + u[:, 1:] * (P[2] - P[0]), 0.5 * (P + np.roll(P, 1, axis=0))])
    d, _ = cKDTree(samples).query(pts)
    assert d.max() <= spacing * (1 + 1e-9)


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 200), st.floats(1e-3, 0.5), st.floats(0.05, 3.0), st.integers(0, 2**32 - 1))
def test_the_reach_grid_keeps_every_point_within_reach(n_samples, reach, spread, seed):
    rng = np.random.default_rng(seed)
    samples = rng.normal(0.0, 0.3, (n_samples, 3)) * rng.uniform(0.05, 1.0, 3) * spread
    points = samples.mean(0) + rng.normal(0.0, 0.5 * spread, (1500, 3))
    # points at exactly the reach from a sample along an axis, and just inside it
    pick = samples[rng.integers(0, n_samples, 300)]
    step = np.eye(3)[rng.integers(0, 3, 300)] * rng.choice([-1.0, 1.0], (300, 1)) * reach
    points = np.vstack([points, pick + step, pick + step * (1 - 1e-12), pick + step / np.sqrt(3.0)])
    d, _ = cKDTree(samples).query(points, distance_upper_bound=reach)
    kept = _within_reach(points, samples, reach)
    assert kept[np.isfinite(d)].all()


def test_cross_and_unit_are_numpys_to_the_bit():
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=(50, 3)) * 1e3, rng.normal(size=(50, 3)) * 1e-3
    for x, y in ((a, b), (a, b[0]), (a[0], b), (a[0], b[0]), (a.astype(np.float32), b), (np.arange(6).reshape(2, 3), [1, 0, 0])):
        want = np.cross(x, y)
        got = cross(x, y)
        assert got.dtype == want.dtype and got.shape == want.shape
        assert np.array_equal(got, want)
    for x in (a, a[0], np.zeros((4, 3)), np.arange(9).reshape(3, 3), [0, 3, 4]):
        want = np.asarray(x) / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-12)
        assert np.array_equal(unit(x), want)



def test_the_neighbour_cut_counts_the_neighbours_under_each_candidates_supported_patch():
    rng = np.random.default_rng(5)
    points, neighbours = rng.normal(size=(60, 3)), rng.normal(size=(40, 3))
    c = 25
    normals, d_up = unit(rng.normal(size=(c, 3))), unit(rng.normal(size=(c, 3)))
    d_side, offsets = unit(cross(d_up, normals)), rng.normal(scale=0.5, size=c)
    supported = rng.random((c, len(points))) < 0.4
    supported[3] = False  # a candidate that supports nothing cuts nothing
    got = _neighbour_cut(points, supported, neighbours, normals, offsets, d_up, d_side, 0.01)
    for j in range(c):
        patch = points[supported[j]]
        if len(patch) == 0:
            assert got[j] == 0.0
            continue
        u, v = neighbours @ d_up[j], neighbours @ d_side[j]
        pu, pv = patch @ d_up[j], patch @ d_side[j]
        under = (u > pu.min()) & (u < pu.max()) & (v > pv.min()) & (v < pv.max()) & (neighbours @ normals[j] - offsets[j] < -0.01)
        assert got[j] == under.mean()
    assert got.max() > 0

def test_a_small_body_through_a_large_face_is_found():
    """A ball 2 cm across poking through the middle of one of a quad's four triangles: no cage edge meets it, only the body's edges cross the face."""
    V = np.array([[-0.4, 0.5, -0.4], [0.4, 0.5, -0.4], [0.4, 0.5, 0.4], [-0.4, 0.5, 0.4]])
    Q = np.array([[0, 1, 2, 3]])
    for x, z in ((0.0, -0.25), (0.13, -0.3), (-0.2, -0.33)):
        body = _sphere_body(radius=0.01, centre=(x, 0.5, z), subdivisions=2)
        np.testing.assert_array_equal(crossing_faces(V, Q, body, 0.0), [0])
        np.testing.assert_array_equal(_brute_crossing(V, Q, body, 0.0), [0])


def test_a_cage_edge_through_a_coarse_body_is_found():
    """A thin quad whose long edge pierces one triangle (8 cm edges) of a coarse body at its middle, far from the body's edges."""
    body = _sphere_body(radius=0.3, centre=(0.0, 0.5, 0.0), subdivisions=2)
    c = body.vertices[body.faces[0]].mean(0)
    n = np.cross(*(body.vertices[body.faces[0][1:]] - body.vertices[body.faces[0][0]]))
    n /= np.linalg.norm(n)
    side = np.cross(n, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    a, b = c - 0.05 * n, c + 0.05 * n
    V = np.array([a, b, b + 0.005 * side, a + 0.005 * side])
    got = crossing_faces(V, np.array([[0, 1, 2, 3]]), body, 0.0)
    np.testing.assert_array_equal(got, [0])
    np.testing.assert_array_equal(_brute_crossing(V, np.array([[0, 1, 2, 3]]), body, 0.0), [0])


# --- sides and refiners' cages ---------------------------------------------------------------


def _upright_chair():
    """The chair's cage on the default body sitting upright, with the body and its pressure."""
    from seatkit.body import load_pose, load_rig, pose_rig
    from seatkit.pressure import solve_pressure
    from seatkit.template import load_template
    from seatkit.plugins import BUILTIN_PLUGINS  # noqa: F401  (the chair file lives in its plugin)
    import seatkit_chair

    body = pose_rig(load_rig("default-male"), load_pose("upright-sitting"), ground=True)
    pressure = solve_pressure(body)
    chair = [t for t in seatkit_chair.seatkit_register_templates() if t.name == "chair"][0]
    return chair.fit([body], [pressure], seed=0), body, pressure


def test_a_cage_oriented_away_from_the_body_is_refused_naming_a_face_and_its_segment():
    import dataclasses

    import pytest

    from seatkit.errors import UnsupportedPoseError
    from seatkit.template.checks import check_cage, wrong_side_faces

    cage, body, _ = _upright_chair()
    assert wrong_side_faces(cage, [body]) == []  # the fitted chair: every supporting face has the body in front
    flipped = dataclasses.replace(cage, faces=cage.faces[:, ::-1].copy())  # the same surface, normals away from the body
    found = wrong_side_faces(flipped, [body])
    assert len(found) >= 5
    whys = [why for _, _, why in found]
    assert all(w.endswith("cm behind it (its normal points away from the body)") or w.startswith("it holds it from above") for w in whys)
    assert any("behind it" in w for w in whys) and any("from above" in w for w in whys)  # the backrest and the seat
    with pytest.raises(UnsupportedPoseError):  # touching the skin from behind, it also crosses the body
        check_cage(flipped, [body], tolerance=0.0)


def test_a_seat_on_the_lap_is_refused_and_the_same_seat_under_the_thighs_is_not():
    import dataclasses

    from seatkit.skeleton import SEGMENT_INDEX
    from seatkit.template.checks import wrong_side_faces

    cage, body, _ = _upright_chair()
    thigh = body.vertices[np.argmax(body.weights, axis=1) == SEGMENT_INDEX["LeftUpLeg"]]
    lo, hi = thigh.min(0), thigh.max(0)
    x0, x1, z0, z1 = lo[0], hi[0], lo[2], hi[2]

    def square(y, down):
        V = np.array([[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]])
        F = np.array([[0, 1, 2, 3]]) if down else np.array([[3, 2, 1, 0]])
        return dataclasses.replace(
            cage, vertices=V, faces=F, face_segments=np.array([SEGMENT_INDEX["LeftUpLeg"]]), face_person=np.array([0]),
            face_labels=("lap",), plane_points=V[:1], plane_normals=np.array([[0.0, 1.0, 0.0]]), vertex_weights=np.ones(4),
            fixed=np.zeros(4, bool), ground=np.zeros(4, bool),
        )

    on_lap = square(hi[1] + 0.03, down=True)
    assert np.cross(on_lap.vertices[2] - on_lap.vertices[0], on_lap.vertices[3] - on_lap.vertices[1])[1] < 0  # normal down, to the thigh
    (found,) = wrong_side_faces(on_lap, [body])
    assert found[0] == 0 and "from above" in found[2]
    under = square(lo[1] - 0.01, down=False)
    assert wrong_side_faces(under, [body]) == []


def test_a_refiners_cage_is_held_to_the_templates_constraints():
    import pytest

    from seatkit.errors import PluginError
    from seatkit.stages import refine
    from seatkit.template.checks import BORDER_TOLERANCE, refined_problems

    cage, body, pressure = _upright_chair()
    assert refined_problems(cage, cage) == []
    g = np.flatnonzero(cage.ground)
    # sliding a ground vertex along its side of the ring is allowed (optimize's slide_border)
    ring = cage.vertices[g][:, [0, 2]]
    a = g[0]
    nb = [b for b in g if b != a and np.isclose(cage.vertices[b, 0], cage.vertices[a, 0], atol=1e-9)]
    slid = cage.vertices.copy()
    slid[a] += 0.3 * (cage.vertices[nb[0]] - cage.vertices[a])
    assert refined_problems(cage, cage.with_vertices(slid)) == []
    # the border moved 25 cm outwards, a ground vertex lifted, a fixed topology changed: refused
    out = cage.vertices.copy()
    centre = ring.mean(0)
    out[g[:, None], [0, 2]] += 0.25 * (ring - centre) / np.linalg.norm(ring - centre, axis=1, keepdims=True)
    (problem,) = refined_problems(cage, cage.with_vertices(out))
    assert "left the template's ground ring by " in problem
    lifted = cage.vertices.copy()
    lifted[g[3], 1] = 0.02
    assert refined_problems(cage, cage.with_vertices(lifted))[0].startswith(f"ground vertex {g[3]} is 20.0 mm off the floor")
    nudged = cage.vertices.copy()
    nudged[g[3], [0, 2]] += 2 * BORDER_TOLERANCE * np.sign(nudged[g[3], [0, 2]] - centre)  # 2 mm outwards, across its side
    assert refined_problems(cage, cage.with_vertices(nudged))

    class Spreader:
        name = "spreader"
        description = "moves the border outwards"

        def refine(self, mesh, bodies, pressures, *, params=None):
            return mesh.with_vertices(out)

    with pytest.raises(PluginError, match=r"^refiner 'spreader' broke the template's constraints: ground vertex \d+ left the template's ground ring by \d+\.\d cm"):
        refine(cage, [("spreader", Spreader(), {})], [body], [pressure])
    # as a build runs it, guarded: its plugin is named too
    from seatkit.plugins import Guarded

    with pytest.raises(PluginError, match=r"^refiner 'spreader' of plugin \"spread\" broke the template's constraints: ground vertex"):
        refine(cage, [("spreader", Guarded(Spreader(), "refiner", "spread"), {})], [body], [pressure])
