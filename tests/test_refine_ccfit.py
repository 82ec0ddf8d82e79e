"""Tests of the ``catmull-clark-fit`` refiner on synthetic targets."""

from __future__ import annotations

import numpy as np
import pytest

from seatkit.errors import SolverError
from seatkit.model import Body, PressureField
from seatkit.refine.ccfit import CatmullClarkFitRefiner, fit_cage, surface_distances
from seatkit.template.flat_patch import flat_patch_cage
from seatkit.subdivision import Cage, build_operators


def height_field(x, z):
    """A smooth seat-like target above y = 0.3 (a bowl with a raised back)."""
    return 0.36 + 0.06 * (x / 0.25) ** 2 + 0.12 * np.clip(-z / 0.3, 0, None) ** 2 - 0.02 * np.cos(np.pi * z / 0.4)


def synthetic_body(n_side: int = 40, segment: int = 0) -> tuple[Body, PressureField]:
    """The underside of a 'body': a sheet sampled from ``height_field``, uniform importance.

    Its triangles face down (-y): the body is above the sheet, so a surface
    point above it is inside the body.
    """
    x, z = np.meshgrid(np.linspace(-0.2, 0.2, n_side), np.linspace(-0.25, 0.45, n_side), indexing="ij")
    pts = np.column_stack([x.ravel(), height_field(x, z).ravel(), z.ravel()])
    n = len(pts)
    idx = np.arange(n).reshape(n_side, n_side)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    tri = pts[faces]
    if np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 1].mean() > 0:
        faces = faces[:, ::-1]
    weights = np.zeros((n, 21))
    weights[:, segment] = 1.0
    body = Body(
        vertices=pts,
        faces=faces,
        weights=weights,
        joints=np.zeros((21, 3)),
        tips=np.zeros((21, 3)),
        segment_mass=np.full(21, 75.0 / 21),
        segment_com=np.zeros((21, 3)),
        name="synthetic",
    )
    pressure = np.full(n, 1000.0)
    field = PressureField(
        force=np.zeros((n, 3)),
        normal_force=pressure * 1e-4,
        pressure=pressure,
        shear=np.zeros(n),
        area=np.full(n, 1e-4),
        contact=np.ones(n, bool),
        joint_force=np.zeros((20, 3)),
        joint_moment=np.zeros((20, 3)),
    )
    return body, field


def flat_cage(height: float = 0.3):
    mesh = flat_patch_cage((-0.22, 0.22), (-0.27, 0.47), height, rows=11, cols=7, margin=0.05)
    from dataclasses import replace

    return replace(mesh, meta={"supported_segments": [0]})


def _signed(mesh, points, level=3):
    ops = build_operators(Cage.from_control_mesh(mesh), level)
    X = ops.limit_points(mesh.vertices)
    N = ops.limit_normals(mesh.vertices)
    return surface_distances(X, N, points)


def test_fit_pulls_flat_patch_onto_smooth_target():
    body, field = synthetic_body()
    mesh = flat_cage()
    out = CatmullClarkFitRefiner().refine(mesh, [body], [field])
    report = out.meta["catmull-clark-fit"]
    before, after = report["before"]["mean_distance"], report["after"]["mean_distance"]
    assert before > 0.05
    assert after < 0.2 * before
    # evaluated independently at a finer level: no point deeper than 5 mm inside
    _, dist, signed = _signed(out, body.vertices, level=4)
    assert (-signed).max() <= 0.005
    assert np.mean(np.abs(signed)) < 0.2 * before
    # topology kept; ground ring untouched
    assert np.array_equal(out.faces, mesh.faces)
    assert np.array_equal(out.vertices[mesh.ground], mesh.vertices[mesh.ground])
    assert report["iterations"] >= 2


def test_fit_resolves_penetration():
    # the patch starts inside the target: a third of the points are below it
    body, field = synthetic_body()
    mesh = flat_cage(height=0.40)
    _, _, signed0 = _signed(mesh, body.vertices)
    assert (-signed0).max() > 0.03
    assert (signed0 < 0).mean() > 0.2
    out = fit_cage(mesh, [body], [field])
    _, _, signed = _signed(out, body.vertices, level=4)
    assert (-signed).max() <= 0.005
    # the report's record of each iteration: the share of the step the trust
    # region let through, and the deepest probe, brought within the limit
    report = out.meta["catmull-clark-fit"]
    assert len(report["step_scale"]) == len(report["depth_history"]) == report["iterations"]
    assert all(0.0 < s <= 1.0 for s in report["step_scale"])
    assert report["before"]["max_penetration"] > 0.03
    assert min(report["depth_history"]) <= report["params"]["max_penetration"]


def test_fit_is_deterministic():
    body, field = synthetic_body(25)
    mesh = flat_cage()
    a = fit_cage(mesh, [body], [field])
    b = fit_cage(mesh, [body], [field])
    assert np.array_equal(a.vertices, b.vertices)


def test_unsupported_segments_give_solver_error():
    body, field = synthetic_body(10, segment=12)  # only the head
    with pytest.raises(SolverError, match="no supported body vertex"):
        fit_cage(flat_cage(), [body], [field])


def test_unmeetable_penetration_limit_raises():
    body, field = synthetic_body(25)
    with pytest.raises(SolverError, match="inside"):
        fit_cage(flat_cage(height=0.55), [body], [field], {"max_iterations": 1, "polish_iterations": 0, "max_penetration": 0.0, "raise_on_penetration": True})


def _build_drawn(tmp_path, family, index, model):
    """The chair (seed 0) for the generalisation benchmark's draw ``index`` of ``family`` (draw seed 2026)."""
    from seatkit.body.generator import draw_pose, pose_yaml
    from seatkit.pipeline import build

    name = f"{family}-{index:03d}"
    path = tmp_path / f"{name}.yaml"
    path.write_text(pose_yaml(draw_pose(np.random.default_rng([2026, index]), family, name)))
    return build({"template": "chair", "seed": 0, "bodies": [{"model": model, "pose": str(path)}]}, write=False, processes=False)


def test_a_hand_hanging_under_the_seat_edge_is_guarded_not_refused(tmp_path):
    """Generated pose seated-008 (the generalisation benchmark's draw, seed 2026) on default-male.

    The hands hang beside the seat, under the edge of the surface, which the
    fit does not pull to: the first fit left them 37 mm inside the furniture
    and the design was refused. The refit guards every body vertex (those
    inside the furniture by the evaluation's ray parity push the surface
    back past them) and keeps them out: the build succeeds within the 5 mm
    guarantee, measured as the evaluation measures it.
    """
    result = _build_drawn(tmp_path, "seated", 8, "default-male")
    report = result.control_mesh.meta["catmull-clark-fit"]
    rounds = report.get("repair_rounds", [])
    assert rounds and rounds[0]["body_in_surface"] > 0.005  # the first fit left a hand inside
    assert max(report["final_depth"].values()) <= 0.005
    ours = result.metrics["ours"][0]
    assert ours["max_penetration_m"] <= 0.005


@pytest.mark.slow
def test_fingertips_through_the_thigh_still_get_a_chair_within_the_limit(tmp_path):
    """Generated pose reclined-153 (the generalisation benchmark's draw, seed 2026) on default-male.

    The left hand rests on the thigh with its fingertips through the thigh's
    skin, down to the seat under it: fits of the template's cages leave them
    9-11 mm inside the furniture. The build still finishes with a design that
    holds the person within the unchanged 5 mm guarantee, measured as the
    evaluation measures it, whichever candidate of the design search it is.
    """
    result = _build_drawn(tmp_path, "reclined", 153, "default-male")
    report = result.control_mesh.meta["catmull-clark-fit"]
    assert max(report["final_depth"].values()) <= 0.005
    ours = result.metrics["ours"][0]
    assert ours["supported"] and ours["max_penetration_m"] <= 0.005 and ours["max_body_depth_m"] <= 0.005
    assert ours["avg_distance_m"] < result.metrics["baseline"][0]["avg_distance_m"]


def test_the_step_observer_sees_the_steps_the_fit_takes_and_changes_nothing():
    # benchmarks/ccfit_steps.py reads each solved step through ccfit._observe:
    # what it reports must be the fit's own steps, and looking must not move the fit
    from seatkit.refine import ccfit

    body, field = synthetic_body(25)
    mesh = flat_cage(height=0.40)
    plain = fit_cage(mesh, [body], [field])
    seen = []
    ccfit._observe = lambda **state: seen.append(state)
    try:
        watched = fit_cage(mesh, [body], [field])
    finally:
        ccfit._observe = None
    assert np.array_equal(plain.vertices, watched.vertices)
    report = watched.meta["catmull-clark-fit"]
    assert len(seen) == report["iterations"]
    for state, share in zip(seen, report["step_scale"]):
        requested = np.linalg.norm(state["solved"] - state["P"], axis=1).max()
        assert share == pytest.approx(min(1.0, state["reach"] / requested))
        # the same rows solved again give the same step
        again = state["solve"](state["w"], state["pen"]).reshape(3, -1).T
        assert np.allclose(again, state["solved"][state["cols"]], atol=1e-9)


def test_a_fit_is_caught_throughout_only_when_no_iterate_came_within_the_limit():
    """A refit from the cage answers a fit caught in the body only if the fit's approach once got within the limit.

    The depth histories are those of two drawn poses' fits (mm): reclined-025
    female's first start, caught from its approach on (its refit from the
    cage ended deeper), and reclined-169 male's last-resort cage, within the
    limit at its 18th iterate and caught again while polishing (its refit
    from the cage is its design).
    """
    from seatkit.refine.ccfit import _caught_throughout

    def report(probes_mm, history_mm):
        return {"after": {"max_penetration": probes_mm / 1000}, "depth_history": [d / 1000 for d in history_mm]}

    reclined_025 = [29.4, 28.4, 28.3, 29.3, 30.6, 29.5, 27.9, 26.5, 25.5, 25.7, 23.4, 22.2, 20.4, 18.9, 20.9, 25.4, 28.7, 30.0]
    reclined_169 = [29.7, 25.5, 26.7, 24.1, 22.6, 24.0, 18.9, 18.2, 17.6, 16.0, 13.4, 10.1, 7.1, 6.6, 4.0, 2.3, 2.1, 1.9, 3.6, 19.6, 18.7]
    assert _caught_throughout(report(20.2, reclined_025), 0.005)
    assert not _caught_throughout(report(18.7, reclined_169), 0.005)
    # probes that end within the limit (a hand inside the furniture is the guarded refit's): not caught
    assert not _caught_throughout(report(1.2, [34.5, 26.0, 12.7, 7.0]), 0.005)
    # a fit with no iterate (nothing recorded) is never judged caught
    assert not _caught_throughout(report(20.0, []), 0.005)
