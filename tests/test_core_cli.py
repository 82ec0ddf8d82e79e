"""The command line: help, plugins, templates, user errors."""

from typer.testing import CliRunner

from seatkit.cli import app

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, list(args), catch_exceptions=False)


def test_help_lists_the_main_commands():
    result = invoke("--help")
    assert result.exit_code == 0
    for command in ("build", "plugins", "templates"):
        assert command in result.output
    assert "seatkit build --template chair" in result.output


def test_plugins_lists_builtins_with_distribution():
    result = invoke("plugins")
    assert result.exit_code == 0
    for name in ("bodies", "qp", "chair", "refiners", "exporters"):
        assert f"{name} (built-in)" in result.output
    assert "seatkit" in result.output


def test_disable_plugin_removes_its_components():
    result = invoke("--disable-plugin", "chair", "plugins")
    assert result.exit_code == 0
    assert "chair (built-in)" not in result.output


def test_unknown_template_is_one_line_on_stderr_and_nonzero(tmp_path):
    result = invoke("build", "--template", "sofa", "--out", str(tmp_path / "o"))
    assert result.exit_code == 1
    lines = [l for l in result.stderr.splitlines() if l.strip()]
    assert len(lines) == 1
    assert lines[0].startswith("seatkit: error: template: unknown template 'sofa'; available:")
    assert not (tmp_path / "o").exists()


def test_bad_recipe_is_refused_before_geometry(tmp_path):
    recipe = tmp_path / "r.yaml"
    recipe.write_text("template: chair\nbodies:\n  - pose: no-such-pose\n")
    result = invoke("build", "--recipe", str(recipe), "--out", str(tmp_path / "o"))
    assert result.exit_code == 1
    assert f"{recipe}:3: bodies[0].pose: unknown pose 'no-such-pose'" in result.stderr
    assert not (tmp_path / "o").exists()


def test_debug_shows_the_traceback_of_a_user_error(tmp_path):
    import pytest

    from seatkit.errors import RecipeError

    with pytest.raises(RecipeError, match="unknown template 'sofa'"):
        runner.invoke(app, ["--debug", "build", "--template", "sofa", "--out", str(tmp_path / "o")], catch_exceptions=False)


def test_unsupported_pose_is_one_error_and_saves_diagnostics_beside_the_output(tmp_path):
    import json

    out = tmp_path / "design"
    result = invoke("build", "--template", "chair", "--pose", "feet-tucked", "--out", str(out))
    assert result.exit_code == 1
    lines = [l for l in result.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and "cannot support" in lines[0] and "diagnostics saved to" in lines[0]
    assert not out.exists()  # no design, no output folder
    saved = json.loads((tmp_path / "design-unsupported.json").read_text())
    assert saved["unsupported_parts"] and "diagnostics" in saved


def test_plugins_and_templates_fit_an_80_column_terminal():
    wide = {}
    for command in ("plugins", "templates"):
        result = runner.invoke(app, [command], env={"COLUMNS": "80"}, catch_exceptions=False)
        assert result.exit_code == 0
        widths = [len(line) for line in result.output.splitlines()]
        assert max(widths) <= 80, f"seatkit {command}: a line of {max(widths)} columns"
        wide[command] = " ".join(result.output.split())
    # nothing was cut: every component and template is still listed in full
    for name in ("catmull-clark-fit", "report-html", "default-female", "crossed-legs", "clearance", "flat-patch"):
        assert name in wide["plugins"]
    for name in ("bench", "chair", "flat-patch", "(Sit & Relax baseline)"):
        assert name in wide["templates"]
