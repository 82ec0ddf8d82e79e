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
