"""Every hook of seatkit's plugin manager: one test each, and a meta-test that keeps it so.

As datasette does for its plugin hooks: the meta-test walks ``pm.hook`` and
requires, for every hook, a documented specification (when it is called,
what it returns, how results combine), a section in docs/plugins.md and a
``test_hook_<name>`` function in this module.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import seatkit
from seatkit.errors import PluginError
from seatkit.plugins import get_plugin_manager
from seatkit.template import Option, load_template

ROOT = Path(__file__).resolve().parents[1]


def _hook_names(pm):
    return sorted(n for n in vars(pm.hook) if n.startswith("seatkit_"))


def test_every_hook_is_documented_and_has_a_test_of_its_own():
    pm = get_plugin_manager(autoload=False)
    names = _hook_names(pm)
    assert len(names) == 7
    docs = (ROOT / "docs" / "plugins.md").read_text()
    here = sys.modules[__name__]
    for name in names:
        caller = getattr(pm.hook, name)
        doc = caller.spec.function.__doc__ or ""
        for part in ("Called:", "Returns:", "Results:"):
            assert part in doc, f"hookspec {name} does not say {part!r}"
        assert caller.spec.opts.get("firstresult") is False or "merged" in doc, name
        assert f"### `{name}`" in docs, f"docs/plugins.md has no section for {name}"
        assert callable(getattr(here, f"test_hook_{name}", None)), f"no test_hook_{name} in tests/test_hooks.py"
        assert caller.spec.function.__annotations__.get("return"), f"hookspec {name} has no return type"


def _pm_with(plugin, name="test-plugin"):
    pm = get_plugin_manager(autoload=False)
    pm.register_plugin(plugin, name)
    return pm


class _Named:
    def __init__(self, name, description="a test component"):
        self.name, self.description = name, description


def test_hook_seatkit_register_body_models():
    class Heavy(_Named):
        def make_body(self, *, params):
            from seatkit.body import load_rig

            return load_rig("default-male", mass=float(params.get("mass", 120.0)))

        def pose(self, rig, pose, *, ground=True):
            from seatkit.body import pose_rig

            return pose_rig(rig, pose, ground=ground)

    class P:
        @seatkit.hookimpl
        def seatkit_register_body_models(self):
            return [Heavy("heavy")]

    reg = _pm_with(P()).registry
    assert reg.plugin_of("body_model", "heavy") == "test-plugin"
    rig = reg.get("body_model", "heavy").make_body(params={})
    assert rig.mass == pytest.approx(120.0)
    # the built-in plugin's models through the same hook
    assert {"default-male", "default-female", "file"} <= set(reg.names("body_model"))
    assert reg.plugin_of("body_model", "default-female") == "bodies"


def test_hook_seatkit_register_pressure_solvers():
    class Half(_Named):
        def solve(self, body, *, contact=None, lam=None, mu=None, exclude=None, options=None):
            raise AssertionError("not called")

    class P:
        @seatkit.hookimpl
        def seatkit_register_pressure_solvers(self):
            return [Half("half")]

    reg = _pm_with(P()).registry
    assert reg.names("pressure_solver") == ["half", "qp"]
    assert reg.plugin_of("pressure_solver", "qp") == "qp"


def test_hook_seatkit_register_templates():
    seen = {}

    class Bound(_Named):
        def fit(self, bodies, pressures, *, params=None, seed=0):
            raise AssertionError("not called")

        def bind(self, steps):
            seen["steps"] = set(steps)
            return Bound("bound-box", "bound")

        def check_params(self, params):
            return None

    class P:
        @seatkit.hookimpl
        def seatkit_register_templates(self):
            return [Bound("box")]

    reg = _pm_with(P()).registry
    # registered under its name, bound to every registered step
    assert reg.get("template", "box").description == "bound"
    assert {"fit-planes", "border", "clearance"} <= seen["steps"]
    assert {"chair", "bench", "saddle", "flat-patch"} <= set(reg.names("template"))


def test_hook_seatkit_register_template_steps():
    class Noop(_Named):
        stage = "blocks"
        requires = ("fit-planes",)
        options = {"n": Option("count", "unused", 1, "", 1, 9)}

        def run(self, state, *, options):
            state.meta["noop"] = options["n"]

    class P:
        @seatkit.hookimpl
        def seatkit_register_template_steps(self):
            return [Noop("noop")]

        @seatkit.hookimpl
        def seatkit_register_templates(self):
            text = (ROOT / "examples/seatkit-stool-plugin/seatkit_stool/stool.yaml").read_text()
            text = text.replace("name: stool", "name: noop-stool").replace("  - step: corners\n", "  - step: noop\n    n: 3\n  - step: corners\n")
            return [load_template(text=text, source="noop-stool.yaml")]

    pm = _pm_with(P())
    reg = pm.registry
    assert pm.problems == []
    assert reg.plugin_of("template_step", "noop") == "test-plugin"
    assert reg.plugin_of("template_step", "fit-planes") == "chair"
    # the template of the same plugin was bound to it (its option checked and defaulted)
    plan = reg.get("template", "noop-stool")._plan
    assert [s.name for s, _ in plan][3] == "noop" and plan[3][1] == {"n": 3}


def test_hook_seatkit_register_refiners():
    class Same(_Named):
        def refine(self, mesh, bodies, pressures, *, params=None):
            return mesh

    class P:
        @seatkit.hookimpl
        def seatkit_register_refiners(self):
            return [Same("same")]

    reg = _pm_with(P()).registry
    assert reg.names("refiner") == ["catmull-clark-fit", "optimize", "same"]


def test_hook_seatkit_register_exporters(tmp_path):
    class Txt(_Named):
        prepare_ahead = False

        def prepare(self):
            return None

        def export(self, result, directory):
            path = Path(directory) / "faces.txt"
            path.write_text(str(len(result.control_mesh.faces)))
            return {"faces": path}

    class P:
        @seatkit.hookimpl
        def seatkit_register_exporters(self):
            return [Txt("txt")]

    pm = _pm_with(P())
    assert pm.registry.plugin_of("exporter", "txt") == "test-plugin"
    recipe = {"template": "flat-patch", "refiners": [], "exporters": ["txt"], "evaluate": {"enabled": False}, "output": str(tmp_path / "out")}
    result = seatkit.build(recipe, pm=pm, processes=False)
    assert (tmp_path / "out" / "faces.txt").read_text() == str(len(result.control_mesh.faces))


def test_hook_seatkit_register_pose_dirs(tmp_path):
    from seatkit.body import list_poses, load_pose

    (tmp_path / "poses").mkdir()
    builtin = (ROOT / "seatkit" / "data" / "poses" / "upright-sitting.yaml").read_text()
    (tmp_path / "poses" / "perched.yaml").write_text(builtin)

    class P:
        @seatkit.hookimpl
        def seatkit_register_pose_dirs(self):
            return [tmp_path / "poses"]

    reg = _pm_with(P()).registry
    assert (tmp_path / "poses").resolve() in [d for d, _ in reg.pose_dirs]
    assert "perched" in [p.name for p in list_poses(reg.pose_dirs)]
    a, b = load_pose("perched", dirs=reg.pose_dirs), load_pose("upright-sitting", dirs=reg.pose_dirs)
    np.testing.assert_allclose(a.rotations, b.rotations)
    # a fresh manager (no such plugin) does not know it
    with pytest.raises(seatkit.errors.RecipeError, match="unknown pose 'perched'"):
        load_pose("perched", dirs=get_plugin_manager(autoload=False).registry.pose_dirs)
    # the same name from two plugins is refused, naming both
    (tmp_path / "poses" / "upright-sitting.yaml").write_text(builtin)
    with pytest.raises(PluginError, match=r"pose .upright-sitting. is defined twice: .*(plugin \"test-plugin\".*plugin \"bodies\"|plugin \"bodies\".*plugin \"test-plugin\")"):
        list_poses(reg.pose_dirs)
