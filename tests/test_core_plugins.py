"""The plugin manager: built-ins, duplicates, broken plugins, blocking."""

import importlib.metadata
import tomllib
from pathlib import Path

import pytest

import seatkit
from seatkit import hookspecs
from seatkit.errors import PluginError, RecipeError
from seatkit.plugins import BUILTIN_PLUGINS, KIND_HOOKS, Registry, get_plugin_manager

ROOT = Path(__file__).resolve().parents[1]


class FakeTemplate:
    def __init__(self, name="stool", description="a fake"):
        self.name = name
        self.description = description

    def fit(self, bodies, pressures, *, params=None, seed=0):
        raise AssertionError("not called")

    def bind(self, steps):
        return self

    def check_params(self, params):
        return None


class FakeRefiner:
    name = "fake-refiner"
    description = "does nothing useful"

    def refine(self, mesh, bodies, pressures, *, params=None):
        return mesh


class TemplatePlugin:
    def __init__(self, name="stool"):
        self._name = name

    @seatkit.hookimpl
    def seatkit_register_templates(self):
        return [FakeTemplate(self._name)]


@pytest.fixture
def pm():
    return get_plugin_manager(autoload=False)


def test_fresh_manager_has_builtins_and_no_problems(pm):
    assert set(pm.infos) == set(BUILTIN_PLUGINS)
    assert all(info.builtin for info in pm.infos.values())
    assert pm.problems == []


def test_fake_plugin_components_are_registered_with_their_plugin(pm):
    pm.register_plugin(TemplatePlugin(), "fake-stool", distribution="fake-dist", version="9.9")
    reg = pm.registry
    assert isinstance(reg.get("template", "stool"), FakeTemplate)
    assert reg.plugin_of("template", "stool") == "fake-stool"
    assert pm.infos["fake-stool"].components == {"template": ["stool"]}
    pm.unregister(name="fake-stool")


def test_duplicate_name_disables_the_later_plugin_naming_both(pm):
    pm.register_plugin(TemplatePlugin("twin"), "first-plugin")
    pm.register_plugin(TemplatePlugin("twin"), "second-plugin")
    reg = Registry(pm)
    assert reg.plugin_of("template", "twin") == "first-plugin"
    assert "chair" in reg.names("template")  # the others are untouched
    (line,) = [p for p in pm.problems if "twin" in p]
    assert line.startswith('plugin "second-plugin" is disabled: ')
    assert '"first-plugin"' in line and "'twin'" in line and "--disable-plugin first-plugin" in line
    assert pm.get_plugin("second-plugin") is None and pm.infos["second-plugin"].disabled


def test_broken_plugin_hook_is_reported_and_rest_keeps_working(pm):
    class Broken:
        @seatkit.hookimpl
        def seatkit_register_refiners(self):
            raise RuntimeError("kaputt")

    class Good:
        @seatkit.hookimpl
        def seatkit_register_refiners(self):
            return [FakeRefiner()]

    pm.register_plugin(Broken(), "broken-one")
    pm.register_plugin(Good(), "good-one")
    reg = pm.registry
    assert "fake-refiner" in reg.names("refiner")
    assert any('"broken-one"' in p and "kaputt" in p for p in pm.problems)


def test_broken_entry_point_import_is_named(monkeypatch):
    class EP:
        name = "exploding"
        dist = None
        group = "seatkit"

        def load(self):
            raise ImportError("no module named exploding_dep")

    real = importlib.metadata.entry_points

    def fake_entry_points(**kw):
        return list(real(**kw)) + [EP()]

    monkeypatch.setattr(importlib.metadata, "entry_points", fake_entry_points)
    pm = get_plugin_manager(autoload=True)
    assert any(p.startswith('Error importing plugin "exploding"') and "exploding_dep" in p for p in pm.problems)
    assert set(BUILTIN_PLUGINS) <= set(pm.infos)
    # with autoload off, the third-party entry point is not even tried
    pm2 = get_plugin_manager(autoload=False)
    assert not pm2.problems


def test_env_var_switches_autoload_off(monkeypatch):
    class EP:
        name = "third"
        dist = None
        group = "seatkit"

        def load(self):
            return TemplatePlugin("third-template")

    real = importlib.metadata.entry_points
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda **kw: list(real(**kw)) + [EP()])
    monkeypatch.setenv("SEATKIT_DISABLE_PLUGIN_AUTOLOAD", "1")
    assert "third" not in get_plugin_manager().infos
    monkeypatch.setenv("SEATKIT_DISABLE_PLUGIN_AUTOLOAD", "0")
    assert "third" in get_plugin_manager().infos


def test_disabled_plugin_is_blocked():
    pm = get_plugin_manager(disabled=["chair"], autoload=False)
    assert "chair" not in pm.infos
    assert pm.is_blocked("chair")


def test_unknown_component_error_lists_available(pm):
    pm.register_plugin(TemplatePlugin("stool"), "fake")
    with pytest.raises(RecipeError, match=r"unknown template 'sofa'; available: .*stool"):
        pm.registry.get("template", "sofa")


def test_component_not_implementing_protocol_is_refused(pm):
    class Bad:
        @seatkit.hookimpl
        def seatkit_register_refiners(self):
            class NoMethod:
                name = "half"
                description = "lacks refine()"

            return [NoMethod()]

    pm.register_plugin(Bad(), "bad")
    reg = Registry(pm)
    assert "half" not in reg.names("refiner") and "optimize" in reg.names("refiner")
    (line,) = pm.problems
    assert line == (
        'plugin "bad" is disabled: its refiner \'half\' does not implement Refiner: '
        "it has no 'refine' (a Refiner has description, name, refine)"
    )


def test_unknown_hook_is_a_plugin_error(monkeypatch):
    import seatkit.plugins as plugins_mod

    class Typo:
        @seatkit.hookimpl
        def seatkit_register_templatez(self):
            return []

    monkeypatch.setattr(plugins_mod, "BUILTIN_PLUGINS", {"typo": "typo_mod", "refiners": "seatkit_refiners"})
    real = plugins_mod.importlib.import_module
    monkeypatch.setattr(plugins_mod.importlib, "import_module", lambda name: Typo() if name == "typo_mod" else real(name))
    monkeypatch.setattr(plugins_mod, "_entry_points", lambda: [])
    pm = get_plugin_manager(autoload=False)
    (line,) = pm.problems
    assert line.startswith('plugin "typo" is disabled: it implements an unknown hook') and "seatkit_register_templatez" in line
    assert pm.registry.names("refiner") == ["catmull-clark-fit", "optimize"]


def test_builtins_are_packages_loaded_by_name_not_entry_points():
    # one way to load a built-in: by module name (as pytest does); entry points are for third parties
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "seatkit" not in data["project"].get("entry-points", {})
    package_dir = data["tool"]["setuptools"]["package-dir"]
    for module in BUILTIN_PLUGINS.values():
        assert module in data["tool"]["setuptools"]["packages"]
        assert (ROOT / package_dir[module] / "__init__.py").is_file()
        text = (ROOT / package_dir[module] / "__init__.py").read_text()
        assert "from seatkit import hookimpl" in text and "HookimplMarker" not in text, module


def test_every_package_is_listed_in_pyproject():
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    listed = set(data["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "seatkit").rglob("__init__.py")}
    found |= {p.parent.name for p in (ROOT / "plugins").glob("*/__init__.py")}
    assert found <= listed, f"packages missing from pyproject: {sorted(found - listed)}"


def test_every_hookspec_is_documented_and_used():
    specs = [n for n in dir(hookspecs) if n.startswith("seatkit_")]
    docs = (ROOT / "docs" / "plugins.md").read_text()
    for name in specs:
        assert getattr(hookspecs, name).__doc__, name
        assert name in docs, f"{name} is not described in docs/plugins.md"
    assert set(KIND_HOOKS.values()) <= set(specs)
