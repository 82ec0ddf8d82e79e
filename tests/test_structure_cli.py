"""``seatkit structure`` and ``seatkit build --structure``: files, the shell's thickness, bad input in one line."""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from seatkit.cli import app
from seatkit.errors import RecipeError

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def chair_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("structure") / "chair"
    done = invoke("build", "--template", "chair", "--out", out, "--quiet")
    assert done.exit_code == 0, done.output
    return out


def test_structure_command_writes_the_figures(chair_dir, tmp_path):
    out = tmp_path / "petg"
    done = invoke("structure", chair_dir, "--out", out, "--material", "petg", "--thickness", 0.003, "--level", 1)
    assert done.exit_code == 0, done.output
    s = json.loads((out / "structure.json").read_text())
    for key in ("max_von_mises_pa", "safety_factor", "max_deflection_m", "mass_kg", "applied_load_n", "floor_reaction_n"):
        assert isinstance(s[key], float), key
    assert s["material"] == "petg" and s["thickness_m"] == 0.003
    assert abs(s["floor_reaction_n"] - s["applied_load_n"]) <= 1e-6 * s["applied_load_n"]
    assert (out / "structure.png").stat().st_size > 10_000
    assert not (chair_dir / "structure.json").exists()  # --out was given


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (("--thickness", 0), "--thickness: expected a number from 0.0001 to 0.5 (m), got 0.0"),
        (("--thickness", -0.003), "--thickness: expected a number from 0.0001 to 0.5 (m), got -0.003"),
        (("--material", "oak"), "--material: expected one of birch-plywood, mdf, pla, petg, aluminium-6061, steel, gfrp, got 'oak'"),
        (("--safety-factor", 0), "--safety-factor: expected a number from 0.001 to 1000, got 0.0"),
    ],
)
def test_bad_flags_are_one_line_and_write_nothing(chair_dir, tmp_path, flags, message):
    out = tmp_path / "bad"
    done = runner.invoke(app, ["structure", str(chair_dir), "--out", str(out), *map(str, flags)])
    assert done.exit_code == 1
    lines = done.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("seatkit: error: ") and message in lines[0], done.output
    assert "Traceback" not in done.output
    assert not out.exists()


def test_not_a_build_folder_is_one_line(tmp_path):
    done = runner.invoke(app, ["structure", str(tmp_path)])
    assert done.exit_code == 1 and "not a seatkit build folder" in done.output and "Traceback" not in done.output


def test_build_with_structure_sizes_and_writes_that_shell(tmp_path):
    recipe = tmp_path / "r.yaml"
    recipe.write_text("template: chair\nevaluate: {baseline: null}\nstructure: {enabled: true, material: petg, size_thickness: true, level: 1, safety_factor: 4}\n")
    out = tmp_path / "out"
    done = invoke("build", "--recipe", recipe, "--out", out, "--quiet")
    assert done.exit_code == 0, done.output
    s = json.loads((out / "structure.json").read_text())
    assert s["sizing"]["safety_factor"] == 4 and s["safety_factor"] >= 4 and s["max_deflection_m"] <= 0.01
    report = json.loads((out / "report.json").read_text())
    assert report["metrics"]["structure"]["thickness_m"] == s["thickness_m"]
    assert "Will it hold? petg" in (out / "report.html").read_text()
    assert (out / "structure.png").is_file()
    import trimesh

    shell = trimesh.load(out / "shell.stl", process=False)
    # the lower sheet lies the sized thickness from the upper one (the designed surface), along the normals
    from seatkit.export.meshes import thick_shell
    from seatkit.state import load_design
    from seatkit.subdivision import limit_surface

    recipe, _, mesh, _ = load_design(out / "design.npz")
    expected = thick_shell(limit_surface(mesh, level=recipe["surface_level"]), s["thickness_m"])
    written = np.unique(np.asarray(shell.vertices, dtype=np.float32), axis=0)  # STL: corners of every triangle
    assert np.array_equal(written, np.unique(np.asarray(expected.vertices, dtype=np.float32), axis=0))


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (("--material", "oak"), "structure.material: expected one of birch-plywood, mdf, pla, petg, aluminium-6061, steel, gfrp, got 'oak'"),
        (("--material", "steal"), "structure.material: expected one of birch-plywood, mdf, pla, petg, aluminium-6061, steel, gfrp, got 'steal'; did you mean 'steel'?"),
        (("--thickness", "0"), "structure.thickness: expected a number from 0.0001 to 0.5 (m), got 0.0"),
        (("--thickness", "-0.02"), "structure.thickness: expected a number from 0.0001 to 0.5 (m), got -0.02"),
        (("--max-deflection", "0"), "structure.max_deflection: expected a number from 1e-06 to 1 (m), got 0.0"),
    ],
)
def test_build_flags_are_checked_before_any_work(tmp_path, flags, message):
    done = runner.invoke(app, ["build", "--template", "chair", *flags, "--out", str(tmp_path / "o")])
    lines = done.output.strip().splitlines()
    assert done.exit_code == 1 and len(lines) == 1 and message in lines[0], done.output
    assert not (tmp_path / "o").exists()


def test_a_design_off_the_floor_is_one_line(chair_dir, tmp_path):
    """design.npz with the cage lifted 10 cm: the structure command refuses it in one line."""
    import io
    import zipfile

    src = zipfile.ZipFile(chair_dir / "design.npz")
    lifted = tmp_path / "lifted"
    lifted.mkdir()
    with zipfile.ZipFile(lifted / "design.npz", "w") as out:
        for name in src.namelist():
            data = src.read(name)
            if name in ("final_vertices.npy", "initial_vertices.npy") or name.startswith("body0_vertices") or name.startswith("body0_joints") or name.startswith("body0_tips") or name.startswith("body0_segment_com"):
                arr = np.load(io.BytesIO(data))
                buf = io.BytesIO()
                np.save(buf, arr + [0.0, 0.1, 0.0])
                data = buf.getvalue()
            out.writestr(name, data)
    done = runner.invoke(app, ["structure", str(lifted), "--level", "1"])
    lines = done.output.strip().splitlines()
    assert done.exit_code == 1 and len(lines) == 1 and "does not meet the floor" in lines[0], done.output
    assert lines[0].startswith(f"seatkit: error: {lifted / 'design.npz'}: the design does not meet the floor"), done.output


_values = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True), st.text(max_size=8), st.lists(st.integers(), max_size=2))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.dictionaries(st.sampled_from(["enabled", "material", "thickness", "size_thickness", "safety_factor", "max_deflection", "level", "layers", "colour"]), _values, max_size=5))
def test_fuzzed_structure_sections_load_or_fail_with_a_recipe_error(section):
    from seatkit.recipe import check_recipe, load_recipe

    try:
        recipe, doc = load_recipe({"template": "chair", "structure": section})
        check_recipe(recipe, _registry(), document=doc)
    except RecipeError as e:
        assert "structure" in str(e)
        return
    assert recipe["structure"]["thickness"] > 0
    if recipe["structure"]["enabled"]:
        assert "structure" in recipe["exporters"] and "shell" in recipe["exporters"]


_REG = []


def _registry():
    if not _REG:
        from seatkit.plugins import get_plugin_manager

        _REG.append(get_plugin_manager().registry)
    return _REG[0]
