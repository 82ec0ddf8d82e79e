"""Recipes and YAML documents: validation with file, line and key path."""

import math

import pytest

from seatkit.errors import RecipeError
from seatkit.recipe import apply_overrides, default_recipe, load_recipe, parse_body_spec
from seatkit.yamlio import parse_yaml


def write(tmp_path, text, name="recipe.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_defaults_fill_every_key(tmp_path):
    recipe, doc = load_recipe(write(tmp_path, "template: chair\n"))
    assert recipe["template"] == "chair"
    assert recipe["bodies"][0]["model"] == "default-male"
    assert recipe["pressure"]["lambda"] == pytest.approx(0.013)
    assert [r["name"] for r in recipe["refiners"]] == ["optimize", "catmull-clark-fit"]
    assert doc.line(("template",)) == 1


def test_type_error_names_file_line_and_key_path(tmp_path):
    path = write(tmp_path, "template: chair\nbodies:\n  - model: default-male\n    pose: 3\nseed: -1\n")
    with pytest.raises(RecipeError) as err:
        load_recipe(path)
    # one line: the first problem in file order, and how many more there are
    assert str(err.value) == f"{path}:4: bodies[0].pose: expected a string, got 3 (and 1 more problem)"


def test_unknown_key_points_at_its_own_line(tmp_path):
    path = write(tmp_path, "template: chair\npressure:\n  solver: qp\n  lamda: 0.1\n")
    with pytest.raises(RecipeError, match=r"recipe.yaml:4: pressure.lamda: unknown key 'lamda'; expected one of"):
        load_recipe(path)


def test_syntax_error_has_line(tmp_path):
    path = write(tmp_path, "template: chair\nbodies: [\n")
    with pytest.raises(RecipeError, match=r"recipe.yaml:\d+: not valid YAML"):
        load_recipe(path)


def test_duplicate_key_is_refused():
    with pytest.raises(RecipeError, match="given twice"):
        parse_yaml("a: 1\na: 2\n", source="x.yaml")


def test_missing_file_is_a_recipe_error(tmp_path):
    with pytest.raises(RecipeError, match="file not found"):
        load_recipe(tmp_path / "nope.yaml")


def test_lambda_inf_and_relative_paths(tmp_path):
    path = write(tmp_path, "pressure: {lambda: inf}\nbodies:\n  - pose: poses/mine.yaml\noutput: out\n")
    recipe, _ = load_recipe(path)
    assert math.isinf(recipe["pressure"]["lambda"])
    assert recipe["bodies"][0]["pose"] == str(tmp_path / "poses" / "mine.yaml")
    assert recipe["output"] == str(tmp_path / "out")


def test_flags_override_recipe_in_seat_order():
    r = apply_overrides(default_recipe(), poses=["a", "b", "c"], bodies=["default-female"], mass=60, seed=4)
    assert [b["pose"] for b in r["bodies"]] == ["a", "b", "c"]
    assert {b["model"] for b in r["bodies"]} == {"default-female"}
    assert all(b["params"]["mass"] == 60 for b in r["bodies"])
    assert r["seed"] == 4
    with pytest.raises(RecipeError, match="2 --pose and 3 --body"):
        apply_overrides(default_recipe(), poses=["a", "b"], bodies=["x", "y", "z"])


def test_body_spec_parsing(tmp_path):
    assert parse_body_spec("default-male") == {"model": "default-male", "params": {}}
    assert parse_body_spec("anny:height=1.8,gender=female") == {
        "model": "anny",
        "params": {"height": 1.8, "gender": "female"},
    }
    spec = parse_body_spec(str(tmp_path / "me.glb"))
    assert spec["model"] == "file" and spec["params"]["path"].endswith("me.glb")
    with pytest.raises(RecipeError, match="cannot read 'height'"):
        parse_body_spec("anny:height")


def test_example_recipes_validate_and_name_registered_components():
    from pathlib import Path

    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import check_recipe

    examples = sorted((Path(__file__).resolve().parents[1] / "examples" / "recipes").glob("*.yaml"))
    assert examples
    registry = get_plugin_manager(autoload=False).registry
    for path in examples:
        recipe, doc = load_recipe(path)
        check_recipe(recipe, registry, document=doc)


# ------------------------------------------------------------------ the Recipe

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_BODY = st.fixed_dictionaries(
    {},
    optional={
        "pose": st.sampled_from(["upright-sitting", "reclined-sitting"]),
        "model": st.sampled_from(["default-male", "default-female"]),
        "params": st.fixed_dictionaries({}, optional={"mass": st.floats(40, 120)}),
        "frame": st.integers(0, 3),
    },
)
_RECIPE = st.fixed_dictionaries(
    {},
    optional={
        "template": st.sampled_from(["chair", "bench"]),
        "bodies": st.lists(_BODY, min_size=1, max_size=3),
        "placement": st.fixed_dictionaries({}, optional={"gap": st.floats(0.0, 1.0)}),
        "pressure": st.fixed_dictionaries(
            {},
            optional={"lambda": st.one_of(st.floats(1e-3, 1.0), st.just("inf")), "mu": st.floats(0.0, 2.0), "exclude": st.lists(st.sampled_from(["Hips", "Head"]), max_size=2)},
        ),
        "refiners": st.lists(st.one_of(st.sampled_from(["optimize", "catmull-clark-fit"]), st.fixed_dictionaries({"name": st.just("optimize"), "params": st.just({})})), max_size=2),
        "exporters": st.lists(st.sampled_from(["usd", "obj", "surface"]), max_size=3, unique=True),
        "surface_level": st.integers(1, 4),
        "evaluate": st.fixed_dictionaries({}, optional={"enabled": st.booleans(), "baseline": st.one_of(st.none(), st.just("flat-patch"))}),
        "output": st.one_of(st.none(), st.just("out/x")),
        "seed": st.integers(0, 2**32 - 1),
    },
)


@settings(max_examples=60, deadline=None)
@given(_RECIPE)
def test_a_normalised_recipe_is_a_valid_recipe_that_normalises_to_itself(data):
    # build() validates every mapping it is given, the normalised ones of
    # load_recipe/apply_overrides too: that must be a no-op on them
    once, _ = load_recipe(data)
    twice, _ = load_recipe(once)
    assert twice == once


def test_check_recipe_returns_a_frozen_recipe_that_reads_as_its_mapping():
    import dataclasses
    import pickle

    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import Recipe, check_recipe, recipe_id

    data = apply_overrides(default_recipe(), template="bench", poses=["upright-sitting", "reclined-sitting"])
    recipe = check_recipe(data, get_plugin_manager().registry)
    assert isinstance(recipe, Recipe)
    assert recipe == data and dict(recipe) == data and recipe.to_dict() == data
    assert recipe.template == recipe["template"] == "bench" and len(recipe.bodies) == 2
    assert "structure" not in recipe and recipe.get("structure", {}) == {}
    with pytest.raises(dataclasses.FrozenInstanceError):
        recipe.template = "chair"
    with pytest.raises(KeyError):
        recipe["nope"]
    assert pickle.loads(pickle.dumps(recipe)) == recipe
    assert recipe_id(recipe) == recipe_id(data)
    # a change goes through a copy, checked again
    other = apply_overrides(recipe, seed=3)
    assert isinstance(other, dict) and other["seed"] == 3 and recipe.seed == 0
    with pytest.raises(RecipeError, match="unknown key 'colour'"):
        Recipe.from_normalised({**data, "colour": "red"})


def test_every_components_options_are_checked_against_one_schema_before_any_geometry(tmp_path):
    # solvers, refiners (the design's and the baseline's), exporters and the structure section: seatkit.options
    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import check_recipe

    registry = get_plugin_manager(autoload=False).registry
    cases = [
        ("pressure:\n  options: {backend: pqip}\n", "3: pressure.options.backend: expected one of auto, newton, piqp, clarabel, got 'pqip'; did you mean 'piqp'?"),
        ("refiners:\n  - {name: optimize, params: {min_edge_lenght: 0.03}}\n", "3: refiners[0].params.min_edge_lenght: refiner 'optimize' has no option 'min_edge_lenght'; its options are: "),
        ("evaluate:\n  baseline_refiners: [{name: catmull-clark-fit, params: {level: 9}}]\n", "3: evaluate.baseline_refiners[0].params.level: expected a whole number from 1 to 4, got 9"),
        ("exporters:\n  - {name: obj, params: {scale: 2}}\n", "3: exporters[0].params.scale: exporter 'obj' has no option 'scale'; its options are: none"),
        ("structure:\n  thicknes: 0.02\n", "3: structure.thicknes: structure has no option 'thicknes'; its options are: "),
        ("structure:\n  layers: 9\n", "3: structure.layers: expected a whole number from 1 to 4, got 9"),
    ]
    for text, expected in cases:
        path = write(tmp_path, "template: chair\n" + text)
        with pytest.raises(RecipeError) as e:
            data, document = load_recipe(path)
            check_recipe(data, registry, document=document)
        assert str(e.value).startswith(f"{path}:{expected}"), str(e.value)
    assert "did you mean 'min_edge_length'?" in _error(tmp_path, registry, cases[1][0])
    assert "did you mean 'thickness'?" in _error(tmp_path, registry, cases[4][0])
    # the defaults come from the same declarations
    from seatkit.options import defaults
    from seatkit.refine import CCFIT_DEFAULTS, OPTIMIZE_DEFAULTS, CatmullClarkFitRefiner, OptimizeRefiner
    from seatkit.structure.build import DEFAULTS, OPTIONS

    assert OPTIMIZE_DEFAULTS == defaults(OptimizeRefiner.options) and CCFIT_DEFAULTS == defaults(CatmullClarkFitRefiner.options)
    assert DEFAULTS == defaults(OPTIONS) and DEFAULTS["thickness"] == 0.02


def _error(tmp_path, registry, text) -> str:
    from seatkit.recipe import check_recipe

    path = write(tmp_path, "template: chair\n" + text)
    with pytest.raises(RecipeError) as e:
        data, document = load_recipe(path)
        check_recipe(data, registry, document=document)
    return str(e.value)
