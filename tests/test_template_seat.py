"""The seat height a designer sets (the ``seat`` step's ``height``): the built design's seat is there, the floor stays.

Measured on the built design: the limit surface's height under the body's
seat point (the lowest pelvis skin), the evaluation's 5 mm figures, the
ground ring on the floor; the refusal of a seat lower than the pose allows,
from a recipe and from ``seatkit build --option``.
"""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from seatkit.cli import app
from seatkit.errors import RecipeError
from seatkit.pipeline import build
from seatkit.recipe import apply_overrides, load_recipe
from seatkit.template.seat import seat_point, surface_below

#: The design is held to this: no body vertex deeper in the furniture, no surface deeper in the skin (m).
GUARANTEE = 0.005

#: A seat depth the reclined default-female takes (its own seat reaches about 0.45 m; ANSI/HFES 100 asks for less than her buttock-popliteal length, 0.385 m), m.
DEPTH_CASE = 0.33


def _recipe(body: str, pose: str, height: float | None = None) -> dict:
    data = {"template": "chair", "bodies": [{"model": body, "pose": pose}], "evaluate": {"baseline": None}}
    if height is not None:
        data["template_params"] = {"steps": {"seat": {"height": height}}}
    recipe, _ = load_recipe(data)
    recipe["output"] = None
    return recipe


def _refused_on_one_line(recipe: dict, option: str, *words: str) -> str:
    """The message of building ``recipe``: one line naming ``template_params.steps.seat.OPTION`` and saying each of ``words``."""
    with pytest.raises(RecipeError) as e:
        build(recipe, write=False, processes=False)
    message = str(e.value)
    assert "\n" not in message and message.startswith(f"template_params.steps.seat.{option}:"), message
    assert all(w in message for w in words), message
    return message


def _surface_below(surface, point) -> float:
    """Height of the highest point of ``surface`` straight below (or at most 5 cm above) ``point``, within 10 cm."""
    y = surface_below(surface.vertices, surface.faces, point, reach=0.1)
    assert y is not None, "no surface under the seat point"
    return y


@pytest.mark.parametrize(("body", "pose", "lift"), [("default-female", "upright-sitting", 0.12), ("p95-male", "reclined-sitting", 0.06)])
def test_a_set_seat_height_is_the_built_designs(body, pose, lift):
    own = build(_recipe(body, pose), write=False, processes=False)
    h0 = float(seat_point(own.bodies[0])[1])
    assert abs(_surface_below(own.surface, seat_point(own.bodies[0])) - h0) <= GUARANTEE  # the seat point is where the seat carries the body
    height = round(h0 + lift, 3)
    result = build(_recipe(body, pose, height), write=False, processes=False)
    body0 = result.bodies[0]
    point = seat_point(body0)
    assert abs(_surface_below(result.surface, point) - height) <= 0.001  # the seat at that height (the design is moved onto it) ...
    assert abs(point[1] - height) <= GUARANTEE  # ... and the body sits on it
    assert body0.vertices[:, 1].min() == pytest.approx(point[1] - h0, abs=GUARANTEE)  # the feet lifted off the floor ...
    ground = np.asarray(result.control_mesh.ground, dtype=bool)
    assert ground.any() and np.allclose(result.control_mesh.vertices[ground, 1], 0.0, atol=1e-9)  # ... the floor stays at y = 0
    ours = result.metrics["ours"][0]
    assert ours["max_penetration_m"] <= GUARANTEE and ours["max_body_depth_m"] <= GUARANTEE  # the 5 mm guarantee holds
    assert result.control_mesh.meta["seat"][0]["set"]


def test_a_seat_lower_than_the_pose_allows_is_refused_on_one_line():
    recipe = _recipe("default-female", "upright-sitting")
    from seatkit.plugins import get_plugin_manager
    from seatkit.stages import place_bodies

    bodies, _ = place_bodies(recipe, get_plugin_manager().registry)
    h0 = float(seat_point(bodies[0])[1])
    with pytest.raises(RecipeError) as e:
        build(_recipe("default-female", "upright-sitting", round(h0 - 0.04, 3)), write=False, processes=False)
    message = str(e.value)
    assert "\n" not in message and message.startswith("template_params.steps.seat.height:")
    assert "below the floor" in message and f"{h0:.3f}" in message  # how low this pose goes
    # the CLI takes the same option, with the same refusal
    out = CliRunner().invoke(app, ["build", "--template", "chair", "--pose", "upright-sitting", "--body", "default-female", "--option", f"seat.height={h0 - 0.04:.3f}", "-q"])
    assert out.exit_code != 0
    lines = [line for line in out.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "seat.height" in lines[0] and "below the floor" in lines[0], out.output


def test_the_option_flag_sets_a_step_option_as_a_recipe_does():
    base, _ = load_recipe({"template": "chair"})
    r = apply_overrides(base, options=["seat.height=0.5", "border.width=0.08"])
    assert r["template_params"]["steps"] == {"seat": {"height": 0.5}, "border": {"width": 0.08}}
    with pytest.raises(RecipeError, match="STEP.KEY=VALUE"):
        apply_overrides(base, options=["seat-height 0.5"])
    # out of the declared range: the recipe's one-line message
    out = CliRunner().invoke(app, ["build", "--template", "chair", "--option", "seat.height=3", "-q"])
    assert out.exit_code != 0 and "template_params.steps.seat.height" in out.output and "0 to 1.5" in out.output, out.output


@pytest.mark.parametrize(("body", "pose", "backrest"), [("default-female", "upright-sitting", 0.7), ("p95-male", "reclined-sitting", 0.62)])
def test_a_set_backrest_height_is_the_built_designs(body, pose, backrest):
    from seatkit.template.seat import backrest_top, seat_height_of

    recipe = _recipe(body, pose)
    recipe["template_params"] = {"steps": {"seat": {"backrest_height": backrest}}}
    result = build(recipe, write=False, processes=False)
    seat_y, seat_z = seat_height_of(result.bodies)
    top = backrest_top(result.surface.vertices, seat_z)
    assert abs(top - seat_y - backrest) <= GUARANTEE  # the backrest's top at that height above the seat, within 5 mm
    ours = result.metrics["ours"][0]
    assert ours["max_penetration_m"] <= GUARANTEE and ours["max_body_depth_m"] <= GUARANTEE  # the 5 mm guarantee holds
    assert result.metrics["dimensions"][0]["back_height_m"] > 0.2  # the back is still carried


def test_a_backrest_lower_than_its_last_row_allows_is_refused_on_one_line():
    recipe = _recipe("default-female", "upright-sitting")
    recipe["template_params"] = {"steps": {"seat": {"backrest_height": 0.2}}}
    _refused_on_one_line(recipe, "backrest_height", "at least")


def _thigh_pressure_ahead(result, depth: float) -> float:
    """The largest contact pressure the built design puts on thigh skin more than ``depth`` from the back of the buttocks along the thighs, Pa."""
    from seatkit.skeleton import SEGMENT_INDEX
    from seatkit.template.grid import segment_of_vertex
    from seatkit.template.seat import seat_axis

    body = result.bodies[0]
    s, back = seat_axis(body)
    thighs = np.isin(segment_of_vertex(body), [SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]])
    ahead = thighs & ((np.asarray(body.vertices) - back) @ s > depth)
    assert ahead.any()
    return float(np.asarray(result.contact_pressures[0].pressure)[ahead].max())


@pytest.mark.parametrize(("body", "pose", "depth"), [("default-female", "reclined-sitting", DEPTH_CASE)])
def test_a_set_seat_depth_is_the_built_designs(body, pose, depth):
    from seatkit.template.seat import seat_depth_of

    own = build(_recipe(body, pose), write=False, processes=False)
    assert seat_depth_of(own.control_mesh, own.bodies)[0] > depth + 0.03  # the pose's own seat reaches further
    recipe = _recipe(body, pose)
    recipe["template_params"] = {"steps": {"seat": {"depth": depth}}}
    result = build(recipe, write=False, processes=False)
    assert abs(seat_depth_of(result.control_mesh, result.bodies)[0] - depth) <= GUARANTEE  # the front edge at that depth, within 5 mm
    assert _thigh_pressure_ahead(result, depth + 0.01) < 1.0  # the thigh beyond the front edge is not carried: the back of the knee is clear
    ours = result.metrics["ours"][0]
    assert ours["max_penetration_m"] <= GUARANTEE and ours["max_body_depth_m"] <= GUARANTEE  # the 5 mm guarantee holds
    assert result.metrics["dimensions"][0]["seat_depth_m"] < own.metrics["dimensions"][0]["seat_depth_m"]  # the carried seat is shorter


def test_a_seat_depth_the_pose_cannot_take_is_refused_on_one_line():
    from seatkit.plugins import get_plugin_manager
    from seatkit.stages import place_bodies
    from seatkit.template.seat import depth_range

    bodies, _ = place_bodies(_recipe("default-female", "upright-sitting"), get_plugin_manager().registry)
    least, most = depth_range(bodies[0])
    assert 0.1 < least < most < 0.6
    for depth, why in ((round(most + 0.05, 3), "past the back of"), (round(least - 0.03, 3), "does not carry")):
        recipe = _recipe("default-female", "upright-sitting")
        recipe["template_params"] = {"steps": {"seat": {"depth": depth}}}
        _refused_on_one_line(recipe, "depth", why, f"from {least:.3f} to {most:.3f} m")  # the range this body in this pose allows
    out = CliRunner().invoke(app, ["build", "--template", "chair", "--pose", "upright-sitting", "--body", "default-female", "--option", f"seat.depth={most + 0.05:.3f}", "-q"])
    assert out.exit_code != 0
    lines = [line for line in out.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "seat.depth" in lines[0] and f"from {least:.3f} to {most:.3f} m" in lines[0], out.output


@pytest.mark.parametrize(("body", "pose", "recline"), [("default-female", "upright-sitting", 15.0), ("default-male", "reclined-sitting", 20.0)])
def test_a_set_recline_is_the_built_backrests(body, pose, recline):
    from seatkit.template.seat import RECLINE_TOLERANCE_DEG, built_recline

    own = build(_recipe(body, pose), write=False, processes=False)
    assert abs(built_recline(own.surface, own.bodies) - recline) > 5.0  # the pose's own backrest is elsewhere
    recipe = _recipe(body, pose)
    recipe["template_params"] = {"steps": {"seat": {"recline": recline}}}
    result = build(recipe, write=False, processes=False)
    assert abs(built_recline(result.surface, result.bodies) - recline) <= RECLINE_TOLERANCE_DEG  # the built backrest at that angle, within 2 deg
    ours = result.metrics["ours"][0]
    assert ours["max_penetration_m"] <= GUARANTEE and ours["max_body_depth_m"] <= GUARANTEE  # the 5 mm guarantee holds
    assert result.metrics["dimensions"][0]["back_height_m"] > 0.3  # the reclined back is carried
    assert abs(seat_point(result.bodies[0])[1] - seat_point(own.bodies[0])[1]) < 0.05  # the sitter still sits: the trunk turned about the hips


def test_a_recline_of_a_pose_without_a_back_to_recline_is_refused_on_one_line():
    recipe = _recipe("default-female", "lying-supine")
    recipe["template_params"] = {"steps": {"seat": {"recline": 15}}}
    _refused_on_one_line(recipe, "recline", "leave the recline out")
    out = CliRunner().invoke(app, ["build", "--template", "chair", "--pose", "upright-sitting", "--option", "seat.recline=80", "-q"])
    assert out.exit_code != 0 and "template_params.steps.seat.recline" in out.output and "-10 to 50" in out.output, out.output
