"""A plugin with an author's mistake leaves the rest of seatkit working and names itself in one line.

Each broken plugin below is one mistake a third-party author makes (a
template name that is taken, a step missing a member, a YAML error in one of
its templates, a hook that does not exist, a step, refiner or exporter that
raises at build time, a misspelt refiner parameter). They are offered as
entry points, as an installed plugin would be; ``seatkit plugins``, ``seatkit
templates`` and a build of the default chair still run, and each broken plugin
is named in one line (``--debug`` shows a build-time bug's traceback).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from typer.testing import CliRunner

import seatkit
import seatkit.plugins as plugins_mod
from seatkit.cli import app
from seatkit.errors import PluginError
from seatkit.template import Option, load_template

STOOL = Path(__file__).resolve().parents[1] / "examples" / "seatkit-stool-plugin" / "seatkit_stool" / "stool.yaml"


class TiltStep:
    """A grid step that works (or raises, with ``broken``)."""

    name = "tilt"
    description = "does nothing, or divides by zero"
    stage = "grid"
    requires = ("join",)
    options = {"amount": Option("number", "how much", 0.0, "m", 0.0, 1.0)}

    def __init__(self, broken=False):
        self.broken = broken

    def run(self, state, *, options):
        if self.broken:
            1 / 0


class NoRequiresStep:
    name = "lean"
    description = "forgets requires"
    stage = "grid"
    options = {}

    def run(self, state, *, options):
        return None


def _tilt_stool(folder: Path, name: str) -> Path:
    """The example stool with ``- step: tilt`` after ``join``, named ``name``."""
    text = STOOL.read_text().replace("name: stool", f"name: {name}", 1)
    text = text.replace("  - step: join\n", "  - step: join\n  - step: tilt\n", 1)
    assert "- step: tilt" in text
    path = folder / f"{name}.yaml"
    path.write_text(text)
    return path


def _plugins(folder: Path) -> dict:
    """Entry-point name -> plugin object, one per mistake (and one that works)."""
    bad_yaml = folder / "broken.yaml"
    bad_yaml.write_text(STOOL.read_text().replace("name: stool", "name: broken-stool", 1).replace("segments: [RightLeg]", "segments: [RightLge]", 1))
    raiser_yaml = _tilt_stool(folder, "tilt-stool")

    class Duplicate:  # a template name the chair plugin registered first
        @seatkit.hookimpl
        def seatkit_register_templates(self):
            return [load_template(_renamed(folder, "chair"))]

    class MissingMember:
        @seatkit.hookimpl
        def seatkit_register_template_steps(self):
            return [NoRequiresStep()]

    class YamlError:
        @seatkit.hookimpl
        def seatkit_register_templates(self):
            return [load_template(STOOL), load_template(bad_yaml)]

    class UnknownHook:
        @seatkit.hookimpl
        def seatkit_register_templatez(self):
            return []

    class Raiser:  # works at registration, raises at build time
        @seatkit.hookimpl
        def seatkit_register_template_steps(self):
            return [TiltStep(broken=True)]

        @seatkit.hookimpl
        def seatkit_register_templates(self):
            return [load_template(raiser_yaml)]

        @seatkit.hookimpl
        def seatkit_register_refiners(self):
            return [BrokenRefiner()]

        @seatkit.hookimpl
        def seatkit_register_exporters(self):
            return [BrokenExporter()]

    return {"dup": Duplicate(), "nomember": MissingMember(), "yamlerr": YamlError(), "typo": UnknownHook(), "raiser": Raiser()}


def _renamed(folder: Path, name: str) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(STOOL.read_text().replace("name: stool", f"name: {name}", 1))
    return path


class BrokenRefiner:
    name = "wobble"
    description = "raises"
    options = {"strength": Option("number", "how hard", 1.0, "1", 0.0, 2.0)}

    def refine(self, mesh, bodies, pressures, *, params=None):
        raise KeyError("vertex_normals")


class BrokenExporter:
    name = "broken-export"
    description = "raises"
    prepare_ahead = False

    def prepare(self):
        return None

    def export(self, result, directory):
        return {"x": Path(directory) / ("x" + 3)}


class _EP:
    def __init__(self, name, plugin):
        self.name, self._plugin, self.dist, self.group = name, plugin, None, "seatkit"

    def load(self):
        return self._plugin


@pytest.fixture
def broken_plugins(monkeypatch, tmp_path):
    eps = [_EP(name, plugin) for name, plugin in sorted(_plugins(tmp_path).items())]
    monkeypatch.setattr(plugins_mod, "_entry_points", lambda: eps)
    monkeypatch.delenv("SEATKIT_DISABLE_PLUGIN_AUTOLOAD", raising=False)
    return tmp_path


def _run(*args):
    return CliRunner().invoke(app, list(args))


def test_each_broken_plugin_is_one_line_and_seatkit_plugins_still_runs(broken_plugins):
    pm = plugins_mod.get_plugin_manager()
    reg = pm.registry
    lines = {p.split('"')[1]: p for p in pm.problems}
    assert set(lines) == {"dup", "nomember", "yamlerr", "typo"}
    assert all(len(line) <= 500 and "\n" not in line for line in pm.problems)
    assert lines["dup"] == (
        'plugin "dup" is disabled: its template \'chair\' is registered by two plugins: "chair" and "dup"; '
        "rename it, or switch the other off with --disable-plugin chair"
    )
    assert lines["nomember"].startswith("plugin \"nomember\" is disabled: its template step 'lean' does not implement TemplateStep: it has no 'requires'")
    assert lines["yamlerr"].startswith('plugin "yamlerr" is disabled: its seatkit_register_templates raised: ')
    assert f"{broken_plugins / 'broken.yaml'}:" in lines["yamlerr"] and "RightLge" in lines["yamlerr"]
    assert lines["typo"].startswith('plugin "typo" is disabled: it implements an unknown hook') and "seatkit_register_templatez" in lines["typo"]
    # every other component still works; the disabled plugins registered nothing
    assert reg.plugin_of("template", "chair") == "chair" and "stool" not in reg.names("template")
    assert {"tilt-stool", "chair", "bench", "flat-patch"} <= set(reg.names("template"))
    assert {"wobble", "optimize"} <= set(reg.names("refiner"))
    with pytest.raises(seatkit.errors.RecipeError, match=r"unknown template 'broken-stool'.*plugin \"yamlerr\" is disabled"):
        reg.get("template", "broken-stool")
    # the command line: the table, and each problem once as a warning
    done = _run("plugins")
    assert done.exit_code == 0, done.output
    assert "chair (built-in)" in done.output and "raiser" in done.output
    for name in ("dup", "nomember", "yamlerr", "typo"):
        assert sum(line.startswith(f'seatkit: warning: plugin "{name}" is disabled: ') for line in done.output.splitlines()) == 1
    assert _run("templates").exit_code == 0


def test_a_default_build_still_runs_beside_the_broken_plugins(broken_plugins):
    out = broken_plugins / "chair-out"
    done = _run("build", "--template", "chair", "--no-refiners", "--exporter", "obj", "-q", "--out", str(out))
    assert done.exit_code == 0, done.output
    assert (out / "cage.obj").is_file() and (out / "report.json").is_file()


def _one_error_line(done) -> str:
    assert done.exit_code == 1
    lines = [l for l in done.output.splitlines() if l.startswith("seatkit: error: ")]
    assert len(lines) == 1, done.output
    assert "Traceback" not in done.output
    return lines[0]


def test_a_step_that_raises_at_build_time_is_one_line_naming_step_plugin_and_template_file(broken_plugins):
    out = broken_plugins / "o"
    done = _run("build", "--template", "tilt-stool", "--no-refiners", "--exporter", "obj", "--out", str(out))
    line = _one_error_line(done)
    assert line == (
        f"seatkit: error: template step 'tilt' of plugin \"raiser\" failed on template 'tilt-stool' ({broken_plugins / 'tilt-stool.yaml'}) "
        "in run(): ZeroDivisionError: division by zero (a bug in the plugin; seatkit --debug shows the traceback)"
    )
    assert not out.exists()
    # --debug: the traceback, down to the plugin's own line
    done = CliRunner().invoke(app, ["--debug", "build", "--template", "tilt-stool", "--no-refiners", "--exporter", "obj", "--out", str(out)])
    assert isinstance(done.exception, PluginError) and isinstance(done.exception.__cause__, ZeroDivisionError)


def test_a_refiner_and_an_exporter_that_raise_are_one_line_each(broken_plugins):
    out = broken_plugins / "o"
    done = _run("build", "--template", "chair", "--refiner", "wobble", "--exporter", "obj", "--out", str(out))
    line = _one_error_line(done)
    assert line.startswith("seatkit: error: refiner 'wobble' of plugin \"raiser\" failed on template 'chair' (")
    assert line.endswith("in refine(): KeyError: 'vertex_normals' (a bug in the plugin; seatkit --debug shows the traceback)")
    done = _run("build", "--template", "chair", "--no-refiners", "--exporter", "obj", "--exporter", "broken-export", "--out", str(out))
    line = _one_error_line(done)
    assert "exporter 'broken-export' of plugin \"raiser\" failed on template 'chair'" in line and "in export(): TypeError: " in line
    assert not out.exists()  # nothing half-written


def test_bad_refiner_parameters_are_refused_before_any_geometry_with_file_line_and_did_you_mean(broken_plugins):
    recipe = broken_plugins / "recipe.yaml"
    recipe.write_text(textwrap.dedent("""\
        template: chair
        refiners:
          - name: wobble
            params: {strenght: 0.5}
        """))
    done = _run("build", "--recipe", str(recipe), "--out", str(broken_plugins / "o"))
    line = _one_error_line(done)
    assert line == (
        f"seatkit: error: {recipe}:4: refiners[0].params.strenght: refiner 'wobble' has no option 'strenght'; "
        "its options are: strength; did you mean 'strength'?"
    )
    recipe.write_text("template: chair\nrefiners: [{name: wobble, params: {strength: 5}}]\n")
    line = _one_error_line(_run("build", "--recipe", str(recipe), "--out", str(broken_plugins / "o")))
    assert line == f"seatkit: error: {recipe}:2: refiners[0].params.strength: expected a number from 0 to 2, got 5"
