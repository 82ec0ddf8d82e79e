"""Default output folders name the design, so that different designs never share one."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from seatkit.pipeline import MAX_DESIGN_NAME, design_name, output_target
from seatkit.recipe import apply_overrides, default_recipe


def _name(**flags) -> str:
    return design_name(apply_overrides(default_recipe(), **flags))


def test_names_tell_template_poses_bodies_and_masses_apart():
    assert _name(template="chair") == "chair-upright-sitting"
    assert _name(template="chair", poses=["reclined-sitting"], bodies=["default-female"], mass=60) == (
        "chair-reclined-sitting-default-female-60kg"
    )
    assert _name(template="bench", poses=["upright-sitting", "reclined-sitting", "crossed-legs-knees"]) == (
        "bench-upright-sitting+reclined-sitting+crossed-legs-knees"
    )
    assert _name(template="chair", poses=["/data/me/my pose.yaml"]) == "chair-my-pose"
    assert _name(template="chair", poses=["walk.bvh"], frame=120) == "chair-walk-frame120"
    assert _name(template="chair", bodies=["/bodies/me.glb"]) == "chair-upright-sitting-me"
    # other body parameters: a short hash, different for different values
    a = _name(template="chair", bodies=["anny:height=0.2"])
    b = _name(template="chair", bodies=["anny:height=0.8"])
    assert a.startswith("chair-upright-sitting-anny-") and a != b
    # named people keep their names
    recipe = default_recipe()
    recipe["bodies"][0]["name"] = "grandad"
    assert design_name(recipe) == "chair-grandad"


def test_every_distinct_library_design_gets_its_own_folder():
    from seatkit.body import list_poses

    names = {_name(template=t, poses=[p.name], bodies=[b]) for t in ("chair", "bench") for p in list_poses() for b in ("default-male", "default-female")}
    assert len(names) == 2 * len(list_poses()) * 2


def test_long_names_are_cut_with_a_hash_and_an_explicit_output_wins():
    poses = ["upright-sitting", "reclined-sitting", "crossed-legs-knees", "armrest-sitting", "leaning-forward", "lounger"]
    long = _name(template="bench", poses=poses)
    other = _name(template="bench", poses=poses[::-1])
    assert len(long) == MAX_DESIGN_NAME and long != other and long.startswith("bench-upright-sitting+")
    recipe = apply_overrides(default_recipe(), output="somewhere/else")
    assert output_target(recipe) == Path("somewhere/else")
    assert output_target(default_recipe()) == Path("seatkit-out/chair-upright-sitting")


def test_a_recipe_file_names_its_folder_unless_flags_change_the_design(tmp_path, monkeypatch):
    import seatkit.pipeline as pl
    from seatkit.cli import app

    seen = []

    def fake_build(recipe, **kw):
        seen.append(recipe["output"])
        raise pl.SeatkitError("stop here")

    monkeypatch.setattr(pl, "build", fake_build)
    recipe = tmp_path / "tall-stool.yaml"
    recipe.write_text("template: chair\n")
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    runner.invoke(app, ["build", "--recipe", str(recipe), "-q"])
    runner.invoke(app, ["build", "--recipe", str(recipe), "--pose", "lounger", "-q"])
    assert seen == [str(Path("seatkit-out") / "tall-stool"), None]  # None: the pipeline names it (chair-lounger)
