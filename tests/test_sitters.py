"""One seat for several sitters (seatkit.sitters): the combined importance, the placement, the build, the recipe."""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from seatkit.errors import RecipeError, SeatkitError
from seatkit.pipeline import build
from seatkit.plugins import get_plugin_manager
from seatkit.recipe import apply_overrides, check_recipe, load_recipe
from seatkit import sitters as sitters_module
from seatkit.sitters import align_sitters, expand_population, seat_reference, shared_sitter, sitter_posers
from seatkit.skeleton import SEGMENT_INDEX
from seatkit.stages import place_bodies, solve_importance

#: The issue's chair: a small woman and a large man upright, a median man reclined.
THREE = [
    {"model": "p5-female", "pose": "upright-sitting"},
    {"model": "p95-male", "pose": "upright-sitting"},
    {"model": "p50-male", "pose": "reclined-sitting"},
]
LIMIT = 0.005
#: How close to the floor a foot that rests on it is kept, m.
FLOOR = 0.003


@pytest.fixture(scope="module")
def registry():
    return get_plugin_manager().registry


def _seated(registry, sitters):
    """The sitters in the canonical frame, their importance, and the same sitters seated on one seat pan (bodies, moves, knee extensions)."""
    recipe = check_recipe(load_recipe({"template": "chair", "sitters": sitters})[0], registry)
    bodies, _ = place_bodies(recipe, registry)
    pressures = solve_importance(recipe, bodies, registry)
    seated = align_sitters(bodies, pressures, sitter_posers(recipe, registry), floor_distance=recipe["evaluate"]["support_distance"])
    return bodies, pressures, seated


@pytest.fixture(scope="module")
def seated_three(registry):
    return _seated(registry, THREE)


@pytest.fixture(scope="module")
def three(seated_three):
    _, pressures, (bodies, _, _, _) = seated_three
    return None, bodies, pressures


def _feet(body):
    """The lowest vertex height of each foot, m."""
    part = np.argmax(body.weights, axis=1)
    return np.array([body.vertices[part == SEGMENT_INDEX[f"{side}Foot"], 1].min() for side in ("Right", "Left")])


def test_the_combination_keeps_every_sitters_own_importance(three):
    _, bodies, pressures = three
    body, pressure = shared_sitter(bodies, pressures)
    assert len(body.vertices) == sum(len(b.vertices) for b in bodies)
    start = 0
    for b, p in zip(bodies, pressures):
        mine = slice(start, start + len(b.vertices))
        start += len(b.vertices)
        # each sitter's map scaled to its own peak: what is important for any sitter is as important in the combination
        assert np.allclose(pressure.importance[mine], p.importance)
        assert pressure.importance[mine].max() == pytest.approx(1.0)
        assert np.array_equal(body.vertices[mine], b.vertices)
        assert np.array_equal(body.weights[mine], b.weights)
    # the skin is the union: each sitter's triangles, on their own vertices
    assert len(body.faces) == sum(len(b.faces) for b in bodies)
    # every sitter carries the same total: a load share is the mean of the sitters' shares
    back = [np.isin(np.argmax(b.weights, 1), [7, 8, 9, 10]) for b in bodies]
    shares = [p.normal_force[m].sum() / p.normal_force.sum() for p, m in zip(pressures, back)]
    assert pressure.normal_force[np.concatenate(back)].sum() / pressure.normal_force.sum() == pytest.approx(np.mean(shares))


def test_one_sitter_is_the_body_itself(three):
    _, bodies, pressures = three
    body, pressure = shared_sitter(bodies[:1], pressures[:1])
    assert body is bodies[0] and pressure is pressures[0]


def test_sitters_share_the_lowest_sitters_seat_with_their_feet_on_the_floor(seated_three):
    before, pressures, (bodies, moves, knees, hips) = seated_three
    own = np.array([seat_reference(b, p) for b, p in zip(before, pressures)])
    refs = np.array([seat_reference(b, p) for b, p in zip(bodies, pressures)])
    # one seat height (a lowered sitter's raised knees lift the lowest pelvis skin, blended with the thighs', a few mm)
    assert np.ptp(refs[:, 0]) < 0.01
    assert np.ptp(refs[:, 1]) < 0.005  # the pelvis's load at one depth (within a few mm, as the height)
    # the seat is the lowest sitter's: the small woman keeps her own seat height, the others come down to it
    assert refs[0, 0] == pytest.approx(own[:, 0].min(), abs=1e-9)
    assert own[1, 0] - refs[1, 0] > 0.1  # the large man comes down more than 10 cm
    for body, move, knee, hip, own_height in zip(bodies, moves, knees, hips, own[:, 0]):
        # every sitter's feet rest on the floor: the lowered ones by their knees' extension, within its limit
        assert np.all(np.abs(_feet(body)) <= FLOOR), body.name
        assert body.vertices[:, 1].min() >= -FLOOR
        assert (knee > 0) == (own_height > refs[0, 0] + 1e-6)
        assert knee <= sitters_module.MAX_KNEE_EXTENSION + 1e-9
        assert 0.0 <= hip <= sitters_module.MAX_HIP_FLEXION + 1e-9
        assert abs(body.joints[0][0]) < 1e-9  # still centred left to right, facing +Z
    # the legs move, the rest of the body does not change shape: the skin the legs do not move, and the hip
    # joints, moved rigidly
    for b0, b, move in zip(before, bodies, moves):
        legs = [SEGMENT_INDEX[f"{side}{part}"] for side in ("Right", "Left") for part in ("UpLeg", "Leg", "Foot")]
        rest = b.weights[:, legs].sum(axis=1) == 0.0
        assert rest.sum() > 1000 and np.allclose(b.vertices[rest], b0.vertices[rest] + move, atol=1e-6)
        hips = [SEGMENT_INDEX["Hips"], SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]]
        assert np.allclose(b.joints[hips], b0.joints[hips] + move, atol=1e-6)
    part = np.argmax(bodies[1].weights, axis=1) == SEGMENT_INDEX["RightFoot"]
    assert bodies[1].vertices[part, 2].mean() > before[1].vertices[part, 2].mean() + 0.1  # the large man's feet forward
    # the large man's flatter thighs are raised (his knees rise) to the small woman's at the seat's front, no higher
    front = sitters_module.seat_front(bodies) - sitters_module.FRONT_BAND
    band = [b.vertices[sitters_module._thigh_band(b, front), 1].min() for b in bodies]
    assert hips[1] > np.radians(3.0) and band[1] == pytest.approx(band[0], abs=1e-3)


def test_a_sitter_who_cannot_bring_the_feet_down_raises_the_seat(registry, monkeypatch):
    pair = [THREE[0], THREE[1]]
    # knees that may extend only 10 degrees: the large man comes down as far as that lets him, the small woman's feet hang
    monkeypatch.setattr(sitters_module, "MAX_KNEE_EXTENSION", float(np.radians(10.0)))
    before, pressures, (bodies, moves, knees, hips) = _seated(registry, pair)
    assert knees[1] <= np.radians(10.0) + 1e-6 and knees[1] + hips[1] > 0.0 and knees[0] == hips[0] == 0.0
    assert moves[1][1] < 0.0 and moves[0][1] > 0.1  # he came down a little, she went up most of the way
    assert np.all(np.abs(_feet(bodies[1])) <= FLOOR)
    assert _feet(bodies[0]).min() > 0.05  # lifted: her feet hang
    monkeypatch.undo()
    # feet that do not both rest on the floor (legs crossed at the knees) are not re-posed: the seat is that sitter's
    crossed = [THREE[0], {"model": "p95-male", "pose": "crossed-legs-knees"}]
    before, pressures, (bodies, moves, knees, hips) = _seated(registry, crossed)
    assert knees == [0.0, 0.0] and hips == [0.0, 0.0]
    assert moves[1][1] == 0.0 and moves[0][1] > 0.05
    assert np.allclose(bodies[1].vertices, before[1].vertices + moves[1])


def test_one_sitter_gives_exactly_the_single_person_design():
    quick = {"template": "chair", "evaluate": {"enabled": False}, "seed": 3}
    alone = build({**quick, "bodies": [THREE[0]]}, write=False, processes=False)
    shared = build({**quick, "sitters": [THREE[0]]}, write=False, processes=False)
    assert np.array_equal(alone.control_mesh.vertices, shared.control_mesh.vertices)
    assert np.array_equal(alone.control_mesh.faces, shared.control_mesh.faces)


@pytest.mark.slow
def test_a_chair_for_a_small_woman_a_large_man_and_a_reclined_man_holds_all_three(tmp_path):
    out = tmp_path / "three"
    result = build({"template": "chair", "sitters": THREE, "exporters": ["report-html"], "output": str(out)}, processes=False)
    ours, base, sharing = result.metrics["ours"], result.metrics["baseline"], result.metrics["sharing"]
    assert len(ours) == len(base) == len(sharing) == 3
    for mine, flat, row in zip(ours, base, sharing):
        assert mine["supported"]
        assert mine["max_penetration_m"] <= LIMIT and mine["max_body_depth_m"] <= LIMIT
        # the cost of sharing: each sitter's own design is there, within the guarantee too
        assert row["own"]["max_penetration_m"] <= LIMIT and row["own"]["max_body_depth_m"] <= LIMIT
        assert row["avg_distance_cost_m"] == pytest.approx(mine["avg_distance_m"] - row["own"]["avg_distance_m"])
        assert mine["avg_distance_m"] < flat["avg_distance_m"]  # ahead of the flat patch for each sitter
    # the seat sized for the shortest legs, as the standards size a fixed seat: the small woman's feet on the floor
    # (the seat's front 88 to 100 % of her popliteal height with shoes) and its front edge clear of her knees
    fit = result.metrics["person_fit"][0]
    assert 0.88 <= fit["seat_height_m"] / fit["seat_height_for_shoes_m"] <= 1.0
    assert fit["seat_depth_m"] < fit["buttock_popliteal_length_m"]
    # one seat: every sitter in the same place, the cage's faces every sitter's
    assert set(np.unique(result.control_mesh.face_person)) == {-1}
    report = json.loads((out / "report.json").read_text())
    assert [r["sitter"] for r in report["metrics"]["sharing"]] == [f"{s['model']}:{s['pose']}" for s in THREE]
    rows = report["metrics"]["sharing"]
    assert max(r["seat_move_m"][1] for r in rows) == 0.0  # the lowest seat contact stays where it was: the small woman's feet reach the floor
    assert [r["knee_extension_deg"] > 0 for r in rows] == [False, True, True]  # the others come down with their legs stretched forward
    assert [r["hip_flexion_deg"] > 0 for r in rows] == [False, True, True]  # and their knees raised to her thighs at the front
    for body in result.bodies:  # every sitter's feet on the floor
        assert np.all(np.abs(_feet(body)) <= FLOOR), body.name
    page = (out / "report.html").read_text()
    assert "own design" in page
    for s in THREE:
        assert s["model"] in page


def test_a_population_expands_to_its_boundary_manikins(registry):
    entries = expand_population({"population": "ansur-ii", "percentiles": [5, 95], "sexes": ["f", "male"], "pose": "reclined-sitting"})
    assert [e["model"] for e in entries] == ["p5-female", "p95-female", "p5-male", "p95-male"]
    assert {e["pose"] for e in entries} == {"reclined-sitting"}
    recipe, _ = load_recipe({"sitters": {"population": "ansur-ii"}})
    assert [b["model"] for b in recipe["bodies"]] == [f"p{q}-{s}" for s in ("female", "male") for q in (5, 50, 95)]
    assert {b["pose"] for b in recipe["bodies"]} == {"upright-sitting"}
    assert recipe["sitters"] == {"shared": True, "population": "ansur-ii"}
    checked = check_recipe(recipe, registry)  # every manikin is a registered body
    assert len(checked["bodies"]) == 6
    # a written recipe (report.json, design.npz) reads back as the same recipe
    again, _ = load_recipe(json.loads(json.dumps(checked.to_dict())))
    assert again == checked.to_dict()


def _error(tmp_path, text: str) -> str:
    path = tmp_path / "r.yaml"
    path.write_text(text)
    with pytest.raises(RecipeError) as e:
        data, doc = load_recipe(path)
        check_recipe(data, get_plugin_manager().registry, document=doc)
    message = str(e.value)
    assert "\n" not in message and "Traceback" not in message
    assert "r.yaml" in message
    return message


def test_a_shared_design_is_evaluated_again_from_its_design_file(tmp_path):
    from typer.testing import CliRunner

    from seatkit.cli import app

    out = tmp_path / "two"
    recipe = {"template": "chair", "sitters": THREE[:2], "refiners": [], "exporters": ["design"], "output": str(out), "evaluate": {"baseline": None}}
    built = build(recipe, processes=False)
    res = CliRunner().invoke(app, ["evaluate", str(out), "--json"])
    assert res.exit_code == 0, res.output
    again = json.loads(res.output[res.output.index("{"):])
    for a, b in zip(again["ours"], built.metrics["ours"]):
        assert a["avg_distance_m"] == pytest.approx(b["avg_distance_m"], rel=1e-6)


def test_recipe_mistakes_in_sitters_are_one_line_naming_file_and_field(tmp_path):
    assert "sitters" in _error(tmp_path, "sitters: [{model: p5-female}]\nbodies: [{model: p5-female}]\n")
    assert "sitters.percentiles" in _error(tmp_path, "sitters: {population: ansur-ii, percentiles: [5, 40]}\n")
    assert "sitters.sexes" in _error(tmp_path, "sitters: {population: ansur-ii, sexes: [x]}\n")
    assert "sitters.population" in _error(tmp_path, "sitters: {population: nhanes}\n")
    assert "sitters" in _error(tmp_path, "sitters: {shared: true}\n")  # the marker needs bodies beside it
    assert "sitters" in _error(tmp_path, "sitters: {percentiles: [5]}\n")
    assert "template" in _error(tmp_path, "template: bench\nsitters: [{model: p5-female}, {model: p95-male}]\n")
    assert "offset" in _error(tmp_path, "sitters: [{model: p5-female, offset: [0, 0, 0]}]\n")
    message = _error(tmp_path, "sitters:\n  - {model: p5-female}\n  - {model: p95-male, pose: no-such-pose}\n")
    assert "sitters[1].pose" in message and "no-such-pose" in message
    assert "sitters[0].model" in _error(tmp_path, "sitters: [{model: nobody}]\n")
    assert "sitters.pose" in _error(tmp_path, "sitters: {population: ansur-ii, pose: no-such-pose}\n")


def test_sitter_flags(registry):
    base = load_recipe(None)[0]
    r = apply_overrides(base, sitters=["p5-female:upright-sitting", "default-male:mass=90:reclined-sitting"])
    assert r["sitters"] == {"shared": True}
    assert [(b["model"], b["pose"]) for b in r["bodies"]] == [("p5-female", "upright-sitting"), ("default-male", "reclined-sitting")]
    assert r["bodies"][1]["params"] == {"mass": 90.0}
    check_recipe(r, registry)
    with pytest.raises(RecipeError, match="BODY:POSE"):
        apply_overrides(base, sitters=["p5-female"])
    with pytest.raises(RecipeError, match="--sitter"):
        apply_overrides(base, sitters=["p5-female:upright-sitting"], poses=["reclined-sitting"])


def test_the_sitter_flag_on_the_command_line_is_one_line(tmp_path):
    from typer.testing import CliRunner

    from seatkit.cli import app

    res = CliRunner().invoke(app, ["build", "--sitter", "p5-female", "--out", str(tmp_path / "x")])
    assert res.exit_code != 0
    assert "BODY:POSE" in res.output and "Traceback" not in res.output


_VALUE = st.one_of(st.none(), st.booleans(), st.integers(-5, 200), st.text(max_size=8), st.lists(st.one_of(st.integers(0, 100), st.text(max_size=3)), max_size=3))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.one_of(
        st.dictionaries(st.sampled_from(["population", "percentiles", "sexes", "pose", "frame", "other"]), _VALUE, max_size=5),
        st.lists(st.dictionaries(st.sampled_from(["model", "pose", "params", "frame", "offset", "x"]), _VALUE, max_size=4), max_size=3),
        _VALUE,
    )
)
def test_any_sitters_value_is_a_recipe_or_one_clear_error(value):
    registry = get_plugin_manager().registry
    try:
        data, doc = load_recipe({"sitters": value})
        recipe = check_recipe(data, registry, document=doc)
    except SeatkitError as e:
        assert "\n" not in str(e).strip()
        return
    assert recipe["sitters"]["shared"] is True and len(recipe["bodies"]) >= 1


def test_a_sitter_lifted_off_the_floor_hangs_the_feet_and_the_seat_carries_the_weight(registry):
    from seatkit.constants import GRAVITY
    from seatkit.pipeline import _seat_sitters

    # a large man with his legs crossed (one foot in the air) cannot come down to the small woman's seat: she goes up to his
    recipe = check_recipe(load_recipe({"template": "chair", "sitters": [THREE[0], {"model": "p95-male", "pose": "crossed-legs-knees"}]})[0], registry)
    bodies, _ = place_bodies(recipe, registry)
    first = solve_importance(recipe, bodies, registry)
    seated, pressures, moves = _seat_sitters(recipe, bodies, first, registry)
    assert moves[1][0][1] == 0.0 and moves[0][0][1] > 0.1 and moves[0][1] == moves[1][1] == 0.0
    woman, man = 0, 1
    lift = seated[woman].vertices[:, 1] - bodies[woman].vertices[:, 1]
    assert lift.min() > 0.1  # the small woman sits on the large man's seat height
    on_floor = bodies[woman].vertices[:, 1] <= recipe["evaluate"]["support_distance"]
    assert on_floor.sum() > 100 and first[woman].normal_force[on_floor].sum() > 0.05 * bodies[woman].mass * GRAVITY  # her feet carried weight
    assert np.abs(pressures[woman].force[on_floor]).max() == 0.0  # nothing under the hanging feet
    # the rest of her body still holds all her weight
    assert pressures[woman].force[:, 1].sum() == pytest.approx(bodies[woman].mass * GRAVITY, rel=1e-3)
    # the highest seat contact is not lifted; his thighs reach past the seat's front (her knees) and carry nothing there
    ahead = np.isin(np.argmax(seated[man].weights, axis=1), sitters_module._LEG_SEGMENTS) & (seated[man].vertices[:, 2] > sitters_module.seat_front(seated))
    assert ahead.sum() > 100 and np.abs(pressures[man].force[ahead]).max() == 0.0
    assert pressures[man].force[:, 1].sum() == pytest.approx(bodies[man].mass * GRAVITY, rel=1e-3)


def test_a_lowered_sitters_importance_is_solved_on_the_new_pose_with_the_feet_on_the_floor(registry):
    from seatkit.constants import GRAVITY
    from seatkit.pipeline import _seat_sitters

    recipe = check_recipe(load_recipe({"template": "chair", "sitters": THREE[:2]})[0], registry)
    bodies, _ = place_bodies(recipe, registry)
    first = solve_importance(recipe, bodies, registry)
    seated, pressures, moves = _seat_sitters(recipe, bodies, first, registry)
    woman, man = 0, 1
    assert moves[woman][0][1] == 0.0 and moves[woman][1] == moves[woman][2] == 0.0  # the lowest seat: she is not moved nor re-posed
    assert moves[man][0][1] < -0.1 and moves[man][1] > 0.0
    feet = np.isin(np.argmax(seated[man].weights, axis=1), [SEGMENT_INDEX["RightFoot"], SEGMENT_INDEX["LeftFoot"]])
    # the feet still carry some of his weight, on the floor where they now rest, and all of it is carried
    assert pressures[man].force[feet, 1].sum() > 0.01 * bodies[man].mass * GRAVITY
    assert pressures[man].force[:, 1].sum() == pytest.approx(bodies[man].mass * GRAVITY, rel=1e-3)
    assert not np.array_equal(pressures[man].importance, first[man].importance)
    # the legs ahead of the seat's front (her knees) carry nothing: the seat ends there; his thighs reach past it
    front = sitters_module.seat_front(seated)
    for who in (woman, man):
        legs = np.isin(np.argmax(seated[who].weights, axis=1), sitters_module._LEG_SEGMENTS)
        ahead = legs & (seated[who].vertices[:, 2] > front)
        assert np.abs(pressures[who].force[ahead]).max() == 0.0
        assert pressures[who].force[legs & ~ahead, 1].sum() > 0.0
        assert pressures[who].force[:, 1].sum() == pytest.approx(bodies[who].mass * GRAVITY, rel=1e-3)
    thighs = np.isin(np.argmax(seated[man].weights, axis=1), sitters_module._THIGHS)
    assert (thighs & (seated[man].vertices[:, 2] > front)).sum() > 100
