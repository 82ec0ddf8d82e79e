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



def _tree(monkeypatch, *, typer_alone: bool):
    """A fresh click tree of the ``seatkit`` command: its values read as ``seatkit`` reads them, or by typer alone."""
    import typer.main

    import seatkit.cli as cli

    with monkeypatch.context() as m:
        if typer_alone:
            m.setattr(cli, "_plain_coercion", lambda params: None)
        group = typer.main.get_command(app)
        for command in group.commands.values():
            command.get_help_option(group.make_context("seatkit", [command.name], resilient_parsing=True))
    return group


def _read(group, name, argv):
    """The values of ``seatkit NAME ARGV`` (each with its type), or how it is refused."""
    try:
        parent = group.make_context("seatkit", [name, *argv])
        values = group.commands[name].make_context(name, list(argv), parent=parent).params
    except Exception as e:  # typer's own UsageError, BadParameter (its vendored click)
        return f"{type(e).__name__}: {e.format_message() if hasattr(e, 'format_message') else e}"
    return {k: (v, type(v), [type(x) for x in v] if isinstance(v, (list, tuple)) else None) for k, v in values.items()}


def test_every_option_reads_as_typer_reads_it(tmp_path, monkeypatch):
    """Options and arguments of every command, read without pydantic where plain (seatkit.cli._PlainCoercion): the same values and refusals as typer's own reading."""
    from pathlib import Path

    file, folder = tmp_path / "recipe.yaml", tmp_path / "folder"
    file.write_text("template: chair\n")
    folder.mkdir()
    ours, typers = _tree(monkeypatch, typer_alone=False), _tree(monkeypatch, typer_alone=True)
    samples = {str: ["chair", "", "-"], Path: [str(file), str(folder), str(tmp_path / "missing"), ""], int: ["3", "x"], float: ["0.5", "inf", "x"]}
    compared = 0
    for name, command in ours.commands.items():
        params = [p for p in command.params if getattr(p, "type_descriptor", None) is not None]
        required = [str(file) for p in params if p.param_type_name == "argument" and p.required]
        assert _read(ours, name, required) == _read(typers, name, required), name  # nothing given: the defaults
        for param in params:
            annotation = param.type_descriptor.annotation
            kind = getattr(annotation, "__args__", (annotation,))[0]
            for value in [None] if getattr(param, "is_flag", False) else samples.get(kind, ["x"]):
                if param.param_type_name == "argument":
                    argv = [value, value] if param.nargs == -1 else [value] + required[1:]
                else:
                    given = [param.opts[0]] if value is None else [param.opts[0], value]
                    argv = required + given * (2 if param.multiple else 1)
                assert _read(ours, name, argv) == _read(typers, name, argv), (name, argv)
                compared += 1
    assert compared > 150


def test_a_default_build_reads_its_options_without_pydantic():
    """typer builds a pydantic adapter for every option it reads; the build's plain options are read without (0.07-0.1 s of start-up)."""
    import subprocess
    import sys

    code = (
        "import sys, typer.main\n"
        "from seatkit.cli import app\n"
        "group = typer.main.get_command(app)\n"
        "argv = ['-q', '--template', 'chair', '--out', 'o', '--pose', 'upright-sitting', '--body', 'default-male']\n"
        "values = group.commands['build'].make_context('build', argv, parent=group.make_context('seatkit', ['build', *argv])).params\n"
        "assert values['pose'] == ['upright-sitting'] and values['mass'] is None, values\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('pydantic', 'click')))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]", done.stdout


def test_a_build_leaves_the_garbage_collector_as_it_found_it(tmp_path):
    """The build pauses collections while it starts up: a program that goes on gets the collector back as it was, on success or refusal."""
    import gc

    try:
        for enabled in (True, False):
            gc.enable() if enabled else gc.disable()
            result = invoke("build", "--template", "sofa", "--out", str(tmp_path / "o"))  # refused while starting up
            assert result.exit_code == 1 and gc.isenabled() is enabled
            # refused by the template stage, after the start-up
            result = invoke("build", "--template", "chair", "--pose", "feet-tucked", "--out", str(tmp_path / f"d{enabled}"))
            assert result.exit_code == 1 and "cannot support" in result.stderr
            assert gc.isenabled() is enabled
            assert not gc.get_freeze_count()  # what the build froze is given back
    finally:
        gc.enable()


def test_import_seatkit_and_its_command_line_import_no_numpy():
    """``import seatkit`` (a plugin's ``from seatkit import hookimpl``, the command's start-up) imports numpy only when a data type is asked for."""
    import subprocess
    import sys

    code = (
        "import sys, seatkit, seatkit.cli\n"
        "assert 'numpy' not in sys.modules, 'numpy imported'\n"
        "from seatkit import Body, ControlMesh, jsonable\n"
        "import seatkit.model, seatkit.io\n"
        "assert Body is seatkit.model.Body and seatkit.Surface is seatkit.model.Surface and jsonable is seatkit.io.jsonable\n"
        "assert set(seatkit.__all__) <= set(dir(seatkit))\n"
        "assert all(getattr(seatkit, name) is not None for name in seatkit.__all__)\n"
        "try:\n"
        "    seatkit.no_such_name\n"
        "except AttributeError as e:\n"
        "    print(e)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "module 'seatkit' has no attribute 'no_such_name'"


def test_the_build_loads_openblas_without_the_threads_it_does_not_use(tmp_path):
    """The build runs numpy and scipy on one thread: its start-up loads their OpenBLAS so, leaving the environment and a user's own setting as they were."""
    import os
    import subprocess
    import sys

    code = (
        "import os, sys, threadpoolctl\n"
        "from seatkit.cli import run\n"
        f"sys.argv = ['seatkit', 'build', '--template', 'sofa', '--out', {str(tmp_path / 'o')!r}]\n"
        "assert run() == 1\n"  # refused once the stages are imported
        "print(sorted({i['num_threads'] for i in threadpoolctl.threadpool_info() if i['internal_api'] == 'openblas'}), os.environ.get('OPENBLAS_NUM_THREADS'))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    if done.stdout.startswith("[]"):
        import pytest

        pytest.skip("this numpy is not built on OpenBLAS")
    assert done.stdout.strip() == "[1] None", done.stdout
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**env, "OPENBLAS_NUM_THREADS": "2"}, check=True)
    assert done.stdout.strip() == "[2] 2", done.stdout


def test_the_command_line_reads_as_the_whole_app_reads_it(monkeypatch, capsys):
    """``seatkit.cli.run`` has typer make only the command the command line names: the same output and exit status as the whole app, every command still listed and suggested."""
    import sys

    import typer.main

    from seatkit import cli

    commands = list(app.registered_commands)
    names = sorted(typer.main.get_command(app).commands)
    for argv in (
        ["build", "--help"],
        ["--disable-plugin", "bench", "templates"],
        ["--disable-plugin=bench", "--debug", "templates"],
        ["build", "--mass", "heavy"],
        ["--help"],
        ["biuld"],
        ["--no-such-option", "build"],
    ):
        monkeypatch.setattr(sys, "argv", ["seatkit", *argv])
        code = cli.run()
        out = capsys.readouterr()
        whole = CliRunner().invoke(app, argv, prog_name="seatkit")
        assert (code, out.out, out.err) == (whole.exit_code, whole.stdout, whole.stderr), argv
        assert app.registered_commands == commands
    monkeypatch.setattr(sys, "argv", ["seatkit", "--help"])
    cli.run()
    listed = capsys.readouterr().out
    assert all(name in listed for name in names) and len(names) > 10
