"""Template engine pieces: schema errors, RANSAC planes, rectangle, border LP, topology."""

from __future__ import annotations

import numpy as np
import pytest

from seatkit.errors import RecipeError
from seatkit.resources import template_path
from seatkit.template import load_template
from seatkit.template.border import place_ground_side
from seatkit.template.checks import self_intersecting_faces, topology_problems
from seatkit.template.planes import fit_support_plane
from seatkit.template.special_cases import minimal_rectangle


def test_chair_template_loads():
    t = load_template(template_path("chair.yaml"))
    assert t.name == "chair"
    assert len(t.spec.rows) == 7 and len(t.spec.columns) == 3
    assert len(t.spec.faces) == 21


@pytest.mark.parametrize("name", ["chair.yaml", "saddle.yaml", "bench.yaml"])
def test_a_shipped_template_meets_the_schema_and_its_text_is_the_one_checked(name):
    # the text of a shipped template is trusted at run time (no jsonschema in
    # a build) only because it is checked here; a changed template must be
    # checked again and its new digest listed
    from seatkit.template.schema import CHECKED_TEMPLATES, TEMPLATE_SCHEMA, template_digest
    from seatkit.yamlio import parse_yaml, read_text, validate

    text = read_text(template_path(name), "YAML file")
    validate(parse_yaml(text, source=name), TEMPLATE_SCHEMA)
    digest = template_digest(text)
    assert digest in CHECKED_TEMPLATES, f"templates/{name} changed: put {digest} in seatkit.template.schema.CHECKED_TEMPLATES for it"


def test_a_shipped_template_edited_is_checked_against_the_schema_again(tmp_path):
    text = template_path("chair.yaml").read_text()
    edited = tmp_path / "chair.yaml"
    edited.write_text(text.replace("role: bridge", "role: bridged", 1))
    with pytest.raises(RecipeError, match=r"chair.yaml:\d+: rows\[\d+\]\.faces\.\w+\.role"):
        load_template(edited)


BAD = """\
name: stool
columns: [a, b]
rows:
  - name: seat
    faces:
      a: {segments: [Hips]}
      b: {segments: [Thigh]}
steps:
  - step: fit-planes
"""


def test_schema_error_names_file_line_and_key():
    with pytest.raises(RecipeError) as e:
        load_template(text=BAD, source="stool.yaml")
    msg = str(e.value)
    assert "stool.yaml:7" in msg and "rows[0].faces.b.segments[0]" in msg


def test_unknown_step_option_is_located():
    text = BAD.replace("Thigh", "LeftUpLeg") + "    colour: red\n"
    with pytest.raises(RecipeError) as e:
        load_template(text=text, source="stool.yaml")
    assert "stool.yaml:10" in str(e.value) and "colour" in str(e.value)


def test_ransac_finds_the_supporting_plane_of_a_box_bottom():
    rng = np.random.default_rng(1)
    # points on a box 0.4 x 0.1 x 0.2, importance on the bottom face (y = 0.3)
    pts = rng.uniform([-0.2, 0.3, -0.1], [0.2, 0.4, 0.1], size=(2000, 3))
    face = rng.integers(0, 3, len(pts))
    pts[face == 0, 1] = 0.3
    imp = (pts[:, 1] < 0.301).astype(float)
    res = fit_support_plane(
        pts, imp, rng=np.random.default_rng(0), iterations=200, support_distance=0.01, max_penetration=0.002,
        body_side=pts.mean(0), bone=np.array([1.0, 0, 0]), lambda_r=0.5,
    )
    assert abs(res.plane.normal[1]) > 0.999 and res.plane.normal[1] > 0
    assert abs(res.plane.signed_distance(np.array([[0.0, 0.3, 0.0]]))[0]) <= 0.004
    # same seed, same plane
    res2 = fit_support_plane(
        pts, imp, rng=np.random.default_rng(0), iterations=200, support_distance=0.01, max_penetration=0.002,
        body_side=pts.mean(0), bone=np.array([1.0, 0, 0]), lambda_r=0.5,
    )
    np.testing.assert_array_equal(res.plane.normal, res2.plane.normal)


def test_a_plane_fit_from_the_same_stream_state_gives_the_same_answer_and_leaves_the_stream_alike():
    rng = np.random.default_rng(3)
    pts = rng.uniform([-0.2, 0.3, -0.1], [0.2, 0.4, 0.1], size=(1500, 3))
    imp = rng.uniform(0.0, 1.0, len(pts))
    kw = dict(iterations=150, support_distance=0.01, max_penetration=0.002, body_side=pts.mean(0), bone=np.array([1.0, 0, 0]), lambda_r=0.5)
    first = np.random.default_rng(7)
    a = fit_support_plane(pts, imp, rng=first, **kw)
    after, next_draw = first.bit_generator.state, first.random()
    again = np.random.default_rng(7)
    b = fit_support_plane(pts, imp, rng=again, **kw)
    # the stream is where the first fit left it: the starts that follow draw the same numbers
    assert again.bit_generator.state == after and again.random() == next_draw
    np.testing.assert_array_equal(a.plane.normal, b.plane.normal)
    np.testing.assert_array_equal(a.plane.point, b.plane.point)
    np.testing.assert_array_equal(a.supported, b.supported)
    assert (a.plane.quality, a.candidates, a.rejected) == (b.plane.quality, b.candidates, b.rejected)
    # each caller owns its answer: changing one changes no later fit
    b.plane.normal[:] = 0.0
    b.supported[:] = False
    b.rejected.clear()
    c = fit_support_plane(pts, imp, rng=np.random.default_rng(7), **kw)
    np.testing.assert_array_equal(c.plane.normal, a.plane.normal)
    np.testing.assert_array_equal(c.supported, a.supported)
    assert c.rejected == a.rejected
    # another stream state, another fit's stream
    other = np.random.default_rng(8)
    fit_support_plane(pts, imp, rng=other, **kw)
    assert other.bit_generator.state != after


def test_minimal_rectangle_of_a_rotated_rectangle():
    a = np.radians(30)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    pts = np.random.default_rng(0).uniform([0, 0], [0.4, 0.1], size=(500, 2))
    pts = np.vstack([pts, [[0, 0], [0.4, 0], [0.4, 0.1], [0, 0.1]]]) @ R.T
    box = minimal_rectangle(pts)
    edges = np.linalg.norm(np.diff(np.vstack([box, box[:1]]), axis=0), axis=1)
    np.testing.assert_allclose(sorted(edges), [0.1, 0.1, 0.4, 0.4], atol=1e-9)


def test_ground_side_is_ordered_and_convex():
    # a profile that goes up and back over itself (a backrest above a seat)
    P = np.array([0.05, 0.3, 0.31, 0.6, 0.58, 0.62])
    H = np.array([0.0, 0.0, 0.45, 0.45, 0.9, 1.1])
    U = np.full(6, 0.05)
    t, convex = place_ground_side(P, H, U, 0.8, 0.02)
    assert convex
    assert np.all(np.diff(np.concatenate([[0], t, [0.8]])) >= 0.02 - 1e-9)


def test_topology_and_self_intersection_checks():
    ids = np.arange(9).reshape(3, 3)
    quads = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], -1).reshape(-1, 4)
    xs, ys = np.meshgrid(np.arange(3.0), np.arange(3.0))
    V = np.stack([xs.ravel(), np.zeros(9), ys.ravel()], 1)
    assert topology_problems(quads, 9) == []
    assert len(self_intersecting_faces(V, quads)) == 0
    # inconsistent winding is reported
    flipped = quads[:, ::-1]
    assert topology_problems(np.vstack([quads[:2], flipped[2:]]), 9)


def test_a_long_bad_step_option_is_quoted_short():
    # a fuzzed template gave a 5135-character message: the value was echoed whole
    from seatkit.options import Option, _check_value

    option = Option("number", "share of a segment's importance that may be occluded", 0.2, "1", 0.0, 1.0)
    _, problem, _ = _check_value(option, "a" * 5000, {})
    assert problem.startswith("expected a number from 0 to 1, got 'aaa")
    assert len(problem) < 200
    assert _check_value(option, 2.5, {})[1] == "expected a number from 0 to 1, got 2.5"


def _seat_and_back(C: int = 3) -> "GridMesh":
    """A bare chair grid (no border): two seat rows at 0.45 m, then four backrest rows leaning back 30 deg to 0.95 m; the body faces +Z."""
    from seatkit.template.grid import GridMesh

    z = [0.25, 0.05, -0.15]
    y = [0.45, 0.45, 0.45]
    for _ in range(4):  # up the backrest, 30 deg behind vertical
        z.append(z[-1] - 0.125 * np.tan(np.radians(30.0)))
        y.append(y[-1] + 0.125)
    xs = np.linspace(-0.22, 0.22, C + 1)
    V = np.stack(np.broadcast_arrays(xs[None, :], np.array(y)[:, None], np.array(z)[:, None]), -1).astype(np.float64)
    R = len(z) - 1
    return GridMesh(
        V, np.zeros((R, C), np.int64), np.zeros((R, C), np.int64), np.full((R, C), "face", object),
        np.full((R, C, 3), np.nan), np.full((R, C, 3), np.nan), np.ones((R, C)), np.zeros((R + 1, C + 1), bool),
    )


def test_the_back_ring_stays_behind_back_rows_a_lift_pushed_back():
    """A lift that pushes the backrest's top row back past the first ring: the ring goes behind it again, and the cage does not fold."""
    from seatkit.template.border import add_border, keep_back_behind
    from seatkit.template.checks import self_intersecting_faces
    from seatkit.template.grid import grid_quads

    meta = {}
    grid = add_border(_seat_and_back(), width=0.05, margin=0.05, min_spacing=0.02, meta=meta)
    G = grid.vertices
    back = -np.array([0.0, 0.0, 1.0])
    # as built: the first ring's back row lies behind every vertex above the ground in its column
    assert np.all(G[-2, 1:-1] @ back >= (G[1:-2, 1:-1] @ back).max(0) - 1e-12)
    assert keep_back_behind(grid, width=0.05, margin=0.05, gap=0.02) == 0  # nothing to do: the cage is unchanged
    np.testing.assert_array_equal(grid.vertices, G)
    quads = grid_quads(grid.label.shape)
    assert len(self_intersecting_faces(G.reshape(-1, 3), quads)) == 0
    # the lift pushes the top row of the back 15 cm back and 20 cm down (lifted off an arm in front of it)
    lifted = G.copy()
    lifted[-3, 2:-2] += [0.0, -0.20, -0.15]
    assert len(self_intersecting_faces(lifted.reshape(-1, 3), quads)) > 0  # the wall from the ring folds over it
    grid.vertices = lifted
    moved = keep_back_behind(grid, width=0.05, margin=0.05, gap=0.02)
    V = grid.vertices
    assert moved == G.shape[1] - 4  # one ring vertex behind each column the lift pushed back
    assert np.all(V[-2, 1:-1] @ back >= (V[1:-2, 1:-1] @ back).max(0) - 1e-12)
    assert np.all(V[-1] @ back >= (V[-2] @ back).max() + 0.05 - 1e-12)  # the ground's back edge margin behind the ring
    assert np.all(V[-1, :, 1] == 0.0) and np.all(V[:-1, 1:-1, 1] >= 0.0)
    assert len(self_intersecting_faces(V.reshape(-1, 3), quads)) == 0
    np.testing.assert_array_equal(V[:-2], lifted[:-2])  # nothing in front of the back ring moves
