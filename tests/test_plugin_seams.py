"""Plugins as real seams: one registry passed in, steps bound and checked at load, recipe step options."""

from __future__ import annotations

import ast
import textwrap
from pathlib import Path

import numpy as np
import pytest

import seatkit
from seatkit.errors import PluginError, RecipeError
from seatkit.plugins import get_plugin_manager
from seatkit.recipe import check_recipe, load_recipe
from seatkit.resources import template_path
from seatkit.skeleton import SEGMENT_INDEX
from seatkit.template import BUILTIN_STEPS, Option, load_template
from seatkit.template.options import options_table

ROOT = Path(__file__).resolve().parents[1]

#: Subpackages below the pipeline: they get what they need passed in.
BELOW_THE_PIPELINE = ("body", "pressure", "template", "refine", "subdivision", "export")


def test_no_module_below_the_pipeline_imports_the_plugin_manager():
    offenders = []
    for sub in BELOW_THE_PIPELINE:
        for path in sorted((ROOT / "seatkit" / sub).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                names = []
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom):
                    mod = node.module or ""
                    names = [mod] + [f"{mod}.{a.name}" for a in node.names]
                if any(n == "seatkit.plugins" or n.startswith("seatkit.plugins.") for n in names):
                    offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert not offenders, f"modules below the pipeline import the plugin manager: {offenders}"


# -- a third-party step, registered only on the plugin manager given to build()


class SeatHeightStep:
    """Records the grid's shape and seat height; moves nothing."""

    name = "seat-height"
    description = "record the height of the highest fitted vertex line"
    stage = "grid"
    requires = ("join",)
    options = {"scale": Option("number", "multiplies the recorded height", 1.0, "1", 0.0, 10.0)}

    def run(self, state, *, options):
        state.meta["seat-height"] = {"shape": list(state.grid.vertices.shape), "height": float(state.grid.vertices[..., 1].max()) * options["scale"]}


STOOL = (ROOT / "examples" / "seatkit-stool-plugin" / "seatkit_stool" / "stool.yaml").read_text()
#: the example stool with the third-party step after its border
STOOL_WITH_STEP = STOOL.rstrip() + "\n  - step: seat-height\n    scale: 2.0\n"


class StepPlugin:
    @seatkit.hookimpl
    def seatkit_register_template_steps(self):
        return [SeatHeightStep()]


class TemplatePlugin:
    def __init__(self, text=STOOL_WITH_STEP, source="stool-plus.yaml"):
        self.text, self.source = text, source

    @seatkit.hookimpl
    def seatkit_register_templates(self):
        return [load_template(text=self.text.replace("name: stool", "name: stool-plus"), source=self.source)]


def _recipe():
    return {"template": "stool-plus", "refiners": [], "exporters": [], "evaluate": {"enabled": False}}


def test_third_party_step_registered_on_the_given_plugin_manager_runs_in_a_build():
    pm = get_plugin_manager(autoload=False)
    pm.register_plugin(StepPlugin(), "height-steps")
    pm.register_plugin(TemplatePlugin(), "stool-plus")
    assert pm.problems == []
    result = seatkit.build(_recipe(), pm=pm, write=False, processes=False)
    mesh = result.initial_mesh
    rec = mesh.meta["seat-height"]
    # it ran last, on the bordered grid (2 rows, 3 columns + two rings each side), with its option
    assert rec["shape"] == [2 + 5, 3 + 5, 3]
    assert rec["height"] == pytest.approx(2.0 * mesh.vertices[:, 1].max())
    # a fresh plugin manager does not know the step: nothing leaks through a global one
    fresh = get_plugin_manager(autoload=False)
    fresh.register_plugin(TemplatePlugin(), "stool-plus")
    with pytest.raises(RecipeError, match="unknown step 'seat-height'"):
        seatkit.build(_recipe(), pm=fresh, write=False, processes=False)


def test_the_same_step_from_a_disabled_plugin_is_refused_cleanly():
    pm = get_plugin_manager(autoload=False)
    pm.set_blocked("height-steps")
    pm.disabled = ("height-steps",)
    pm.register_plugin(StepPlugin(), "height-steps")  # blocked: not registered
    pm.register_plugin(TemplatePlugin(), "stool-plus")
    assert "height-steps" not in pm.infos
    with pytest.raises(RecipeError) as e:
        seatkit.build(_recipe(), pm=pm, write=False, processes=False)
    msg = str(e.value)
    line = 1 + STOOL_WITH_STEP.splitlines().index("  - step: seat-height")
    assert "\n" not in msg
    assert f"stool-plus.yaml:{line}: steps[6].step: unknown step 'seat-height'" in msg
    assert "(disabled plugins: height-steps)" in msg
    assert any("stool-plus" in p and "seat-height" in p for p in pm.problems)


def test_a_misspelt_option_of_a_plugin_step_is_refused_at_load_with_file_and_line():
    pm = get_plugin_manager(autoload=False)
    pm.register_plugin(StepPlugin(), "height-steps")
    pm.register_plugin(TemplatePlugin(STOOL_WITH_STEP.replace("scale: 2.0", "scael: 2.0")), "stool-plus")
    line = 1 + STOOL_WITH_STEP.splitlines().index("    scale: 2.0")
    # found when the registry is built, before any geometry
    pm.registry  # noqa: B018
    assert any(f"stool-plus.yaml:{line}: steps[6].scael: step 'seat-height' has no option 'scael'" in p for p in pm.problems)
    with pytest.raises(RecipeError, match=r"did you mean 'scale'\?"):
        check_recipe(load_recipe(_recipe())[0], pm.registry)


# -- a template author's mistakes: one line with file, line, key path and what was expected

CHAIR = template_path("chair.yaml").read_text()


def _bind(text):
    return load_template(text=text, source="my-chair.yaml").bind(BUILTIN_STEPS)


def _line_of(text, needle, start=0):
    lines = text.splitlines()
    return 1 + next(i for i in range(start, len(lines)) if needle in lines[i])


def _one_line(fn, text):
    with pytest.raises(RecipeError) as e:
        fn(text)
    msg = str(e.value)
    assert "\n" not in msg and "Traceback" not in msg
    return msg


def test_mistyped_option_is_one_located_line():
    text = CHAIR.replace("    width: 0.05                 # m", "    width: five")
    msg = _one_line(load_template_text, text)
    assert msg.startswith(f"my-chair.yaml:{_line_of(text, 'width: five')}: steps[11].width: expected a number from 0 to 1 (m), got 'five'")


def load_template_text(text):
    return load_template(text=text, source="my-chair.yaml")


def test_steps_in_the_wrong_order_are_one_located_line():
    # outer-columns before corners (the KeyError (1, 1) of old)
    text = CHAIR.replace("  - step: corners\n", "").replace("  - step: supportability\n", "  - step: corners\n  - step: supportability\n")
    msg = _one_line(_bind, text)
    assert msg.startswith(f"my-chair.yaml:{_line_of(text, '- step: outer-columns')}: steps[6].step: step 'outer-columns' needs step 'corners' before it")
    # a per-person step after the grid was joined
    text = CHAIR.replace("  - step: join\n", "").replace("  - step: armrests\n", "  - step: join\n  - step: corners\n  - step: armrests\n")
    msg = _one_line(_bind, text)
    assert "steps[10].step: step 'corners' fits each person's faces, but step 'join' before it already joined them" in msg


def test_a_role_in_a_column_that_cannot_hold_it_is_one_located_line():
    text = CHAIR.replace("      middle: {segments: [Hips], width_fraction: 0.5, label: hips.middle}", "      middle: {role: outer, segments: [Hips], label: hips.middle}")
    msg = _one_line(load_template_text, text)
    assert msg.startswith(f"my-chair.yaml:{_line_of(text, 'role: outer, segments: [Hips], label: hips.middle')}: rows[3].faces.middle.role: role 'outer'")
    assert "'right' or 'left'" in msg
    text = CHAIR.replace("      right:  {segments: [RightFoot], label: foot.right}", "      right:  {role: bridge, label: foot.right}")
    msg = _one_line(load_template_text, text)
    assert "rows[0].faces.right.role: role 'bridge' joins the 'fit' faces on both sides" in msg


def test_an_unknown_step_is_caught_at_load_with_did_you_mean():
    text = CHAIR.replace("  - step: border\n", "  - step: bordr\n")
    msg = _one_line(_bind, text)
    assert msg.startswith(f"my-chair.yaml:{_line_of(text, '- step: bordr')}: steps[11].step: unknown step 'bordr'")
    assert "did you mean 'border'?" in msg


def test_an_unknown_option_of_a_builtin_step_says_did_you_mean():
    text = CHAIR.replace("    min_width: 0.06", "    min_widht: 0.06")
    msg = _one_line(load_template_text, text)
    assert f"my-chair.yaml:{_line_of(text, 'min_widht')}: steps[7].min_widht: step 'outer-columns' has no option 'min_widht'" in msg
    assert "did you mean 'min_width'?" in msg


def test_a_missing_required_option_is_refused():
    class Needy:
        name = "needy"
        description = "needs a count"
        stage = "blocks"
        requires = ()
        options = {"n": Option("count", "how many", required=True, minimum=1)}

        def run(self, state, *, options):
            raise AssertionError("not run")

    text = CHAIR.replace("  - step: corners\n", "  - step: corners\n  - step: needy\n")
    with pytest.raises(RecipeError, match=r"steps\[7\]: step 'needy' needs option 'n' \(a whole number >= 1"):
        load_template(text=text, source="my-chair.yaml").bind({**BUILTIN_STEPS, "needy": Needy()})


# -- recipes reach step options


def _recipe_file(tmp_path, body):
    path = tmp_path / "recipe.yaml"
    path.write_text(textwrap.dedent(body))
    return path


def _check(path):
    recipe, doc = load_recipe(path)
    check_recipe(recipe, get_plugin_manager(autoload=False).registry, document=doc)


def test_recipe_step_option_errors_name_file_line_and_key(tmp_path):
    path = _recipe_file(tmp_path, """\
        template: chair
        template_params:
          steps:
            border: {widht: 0.1}
        """)
    with pytest.raises(RecipeError) as e:
        _check(path)
    assert str(e.value).startswith(f"{path}:4: template_params.steps.border.widht: step 'border' has no option 'widht'")
    assert "did you mean 'width'?" in str(e.value)
    path = _recipe_file(tmp_path, """\
        template: chair
        template_params:
          steps:
            11: {width: 2}
        """)
    with pytest.raises(RecipeError, match=r"recipe.yaml:4: template_params.steps.11.width: expected a number from 0 to 1 \(m\), got 2"):
        _check(path)
    path = _recipe_file(tmp_path, """\
        template: chair
        template_params:
          steps:
            no-such-step: {width: 0.1}
        """)
    with pytest.raises(RecipeError, match=r"recipe.yaml:4: template_params.steps.no-such-step: template 'chair' has no step 'no-such-step'; its steps are 0: pose-rule, 1: fit-planes"):
        _check(path)


def test_template_params_errors_have_file_and_line(tmp_path):
    # issue 20, item 8: a template parameter error names the recipe's file and line
    path = _recipe_file(tmp_path, """\
        template: chair
        seed: 1
        template_params:
          ransac_iterations: -3
        """)
    with pytest.raises(RecipeError, match=r"recipe.yaml:4: template_params.ransac_iterations: expected a whole number from 1 to 20000"):
        _check(path)
    path = _recipe_file(tmp_path, """\
        template: chair
        template_params:
          border: {width: 0.1}
        """)
    with pytest.raises(RecipeError) as e:
        _check(path)
    assert str(e.value).startswith(f"{path}:3: template_params.border: unknown parameter of template 'chair'")
    assert "step options go under steps:" in str(e.value)
    path = _recipe_file(tmp_path, """\
        template: flat-patch
        template_params: {rowz: 3}
        """)
    with pytest.raises(RecipeError, match=r"recipe.yaml:2: template_params.rowz: template 'flat-patch' has no option 'rowz'; its options are: cols, .*; did you mean 'rows'\?$"):
        _check(path)


@pytest.fixture(scope="module")
def stool_inputs():
    from seatkit.pipeline import make_bodies, solve_importance
    from seatkit.recipe import default_recipe

    registry = get_plugin_manager(autoload=False).registry
    recipe = default_recipe()
    bodies = make_bodies(recipe, registry)
    return bodies, solve_importance(recipe, bodies, registry)


def test_recipe_step_options_reach_the_step_by_label_and_by_index(stool_inputs):
    bodies, pressures = stool_inputs
    stool = load_template(text=STOOL.replace("  - step: border\n", "  - step: border\n    label: ground\n"), source="stool.yaml")
    default = stool.fit(bodies, pressures, seed=0)
    by_label = stool.fit(bodies, pressures, seed=0, params={"steps": {"ground": {"width": 0.12, "margin": 0.2}}})
    by_index = stool.fit(bodies, pressures, seed=0, params={"steps": {5: {"width": 0.12, "margin": 0.2}}})
    assert default.meta["border"]["width"] == 0.04 and default.meta["border"]["margin"] == 0.05
    assert by_label.meta["border"]["width"] == 0.12 and by_label.meta["border"]["margin"] == 0.2
    np.testing.assert_array_equal(by_label.vertices, by_index.vertices)
    # a wider ring and margin make a wider ground rectangle: by both differences, on both sides
    def extent(m):
        r = np.array(m.meta["border"]["rectangle"])
        return r[:, 0].max() - r[:, 0].min()

    assert extent(by_label) == pytest.approx(extent(default) + 2 * ((0.12 - 0.04) + (0.2 - 0.05)), abs=0.01)


# -- the saddle stool: YAML only


def _front_wall_z(mesh):
    n_rows = 2 + 5  # 2 template rows, two rings on each side
    V = mesh.vertices.reshape(n_rows, -1, 3)
    return V[0, 2:-2, 2], V[1, 2:-2]  # ground row z, first ring


@pytest.mark.parametrize("pose", ["upright-sitting", "reclined-sitting", "leaning-forward"])
def test_saddle_is_yaml_only_and_the_legs_hang_in_front_of_its_front_wall(pose, tmp_path):
    from seatkit.pipeline import make_bodies, solve_importance
    from seatkit.recipe import default_recipe
    from seatkit.template.render import render_cage

    registry = get_plugin_manager(autoload=False).registry
    assert registry.plugin_of("template", "saddle") == "chair"
    assert not (ROOT / "templates" / "saddle.py").exists()
    recipe = default_recipe()
    recipe["bodies"][0]["pose"] = pose
    bodies = make_bodies(recipe, registry)
    pressures = solve_importance(recipe, bodies, registry)
    mesh = registry.get("template", "saddle").fit(bodies, pressures, seed=0)  # check_cage passed inside
    assert mesh.meta["border"]["front_wall"] == "behind-calves"
    # it carries the buttocks and thighs, every listed segment counted
    assert mesh.meta["supported_segments"] == sorted(SEGMENT_INDEX[s] for s in ("Hips", "RightUpLeg", "LeftUpLeg"))
    # the lower legs below the first ring are in front of the front wall (the body faces +Z)
    body = bodies[0]
    dominant = body.weights.argmax(1)
    legs = np.isin(dominant, [SEGMENT_INDEX[s] for s in ("RightLeg", "LeftLeg", "RightFoot", "LeftFoot")])
    ground_z, ring = _front_wall_z(mesh)
    low = legs & (body.vertices[:, 1] < ring[:, 1].min()) & (body.vertices[:, 1] > 0.02)
    assert low.sum() > 500
    x, y, z = body.vertices[low].T
    order = np.argsort(ring[:, 0])
    ring_z = np.interp(x, ring[order, 0], ring[order, 2])  # the wall's top edge over each leg vertex
    ground = np.interp(x, ring[order, 0], ground_z[order])
    wall_z = ground + (ring_z - ground) * y / ring[:, 1].min()  # the wall at the vertex's height (it slopes back)
    assert (z - wall_z).min() > 0.005, f"a lower-leg vertex is {-(z - wall_z).min():.3f} m behind the front wall"
    out = render_cage(mesh, bodies, tmp_path / f"saddle-{pose}.png", views=("side",))
    assert out.stat().st_size > 10_000


# -- plugin management


def test_disable_plugin_refuses_an_unknown_name_listing_the_names():
    with pytest.raises(PluginError) as e:
        get_plugin_manager(disabled=["chiar"], autoload=False)
    msg = str(e.value)
    assert "--disable-plugin 'chiar': no such plugin; did you mean 'chair'?" in msg
    assert "the plugins are: " in msg and "bench" in msg and "refiners" in msg


def test_disabling_a_plugin_removes_every_component_steps_included():
    pm = get_plugin_manager(disabled=["chair"], autoload=False)
    reg = pm.registry
    assert reg.names("template_step") == []
    assert "chair" not in reg.names("template") and "saddle" not in reg.names("template")
    # the bench (another plugin) uses the chair plugin's steps: refused, saying why
    with pytest.raises(RecipeError) as e:
        reg.get("template", "bench")
    msg = str(e.value)
    assert "template 'bench' cannot be used: " in msg and "bench.yaml:" in msg
    assert "steps[0].step: unknown step 'pose-rule'" in msg and "(disabled plugins: chair)" in msg
    assert "flat-patch" in reg.names("template")  # the refiners plugin is untouched
    pm2 = get_plugin_manager(disabled=["bodies"], autoload=False)
    assert pm2.registry.names("body_model") == ["anny"] and pm2.registry.pose_dirs == []


def test_an_uninstalled_checkout_says_what_failed_to_import(monkeypatch):
    import importlib

    import seatkit.plugins as plugins_mod

    real = importlib.import_module

    def no_builtins(name, *a, **k):
        if name in plugins_mod.BUILTIN_PLUGINS.values():
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real(name, *a, **k)

    monkeypatch.setattr(plugins_mod.importlib, "import_module", no_builtins)
    pm = get_plugin_manager(autoload=False)
    assert pm.infos == {}
    with pytest.raises(RecipeError) as e:
        pm.registry.get("template", "chair")
    msg = str(e.value)
    assert msg.startswith("unknown template 'chair'; available: none; seatkit's built-in plugins ")
    assert "this checkout is not installed; run pip install -e . in it" in msg
    assert f"({len(plugins_mod.BUILTIN_PLUGINS)} plugins failed to load, e.g. Error importing plugin " in msg
    assert "ModuleNotFoundError: No module named 'seatkit_" in msg
    assert pm.problems[-1] == plugins_mod.NOT_INSTALLED
    # a built-in that fails for another reason is named as it is
    monkeypatch.setattr(plugins_mod.importlib, "import_module", lambda name, *a, **k: (_ for _ in ()).throw(ImportError("libfoo.so missing")) if name == "seatkit_chair" else real(name, *a, **k))
    pm = get_plugin_manager(autoload=False)
    with pytest.raises(RecipeError, match=r"plugins that failed to load: Error importing plugin \"chair\": ImportError: libfoo.so missing$"):
        pm.registry.get("template", "chair")


def test_an_exporter_without_prepare_is_refused_at_registration():
    class Old:
        name = "old"
        description = "no prepare"

        def export(self, result, directory):
            return {}

    class P:
        @seatkit.hookimpl
        def seatkit_register_exporters(self):
            return [Old()]

    pm = get_plugin_manager(autoload=False)
    pm.register_plugin(P(), "old-exporters")
    assert "old" not in pm.registry.names("exporter")
    (line,) = pm.problems
    assert line.startswith('plugin "old-exporters" is disabled: its exporter \'old\' does not implement Exporter: ')
    assert "it has no 'prepare', 'prepare_ahead'" in line
    reg = get_plugin_manager(autoload=False).registry
    ahead = {n for n, e, _ in reg.items("exporter") if e.prepare_ahead}
    assert ahead == {"usd", "usdc", "shell", "report-html"}


def test_baseline_refiners_come_from_the_recipe(tmp_path):
    recipe, _ = load_recipe({"template": "chair"})
    assert recipe["evaluate"]["baseline_refiners"] == [{"name": "catmull-clark-fit", "params": {}}]
    recipe, _ = load_recipe({"evaluate": {"baseline_refiners": ["optimize", {"name": "catmull-clark-fit", "params": {"level": 2}}]}})
    assert [r["name"] for r in recipe["evaluate"]["baseline_refiners"]] == ["optimize", "catmull-clark-fit"]
    path = _recipe_file(tmp_path, """\
        evaluate:
          baseline_refiners: [catmull-clark-fitt]
        """)
    with pytest.raises(RecipeError, match=r"recipe.yaml:2: evaluate.baseline_refiners\[0\]: unknown refiner 'catmull-clark-fitt'.*did you mean 'catmull-clark-fit'"):
        _check(path)


# -- the docs tables are the schemas


def test_docs_option_tables_are_generated_from_the_step_schemas():
    docs = (ROOT / "docs" / "templates.md").read_text()
    for name, step in BUILTIN_STEPS.items():
        block = f"<!-- options of {name} -->\n{options_table(step)}\n<!-- end -->"
        assert block in docs, f"docs/templates.md: the options table of step {name!r} is not the one its schema gives; run python -m seatkit.template.steps docs/templates.md"



def test_docs_option_tables_of_refiners_are_generated_from_their_declarations():
    from seatkit.options import options_table as table
    from seatkit.template.flat_patch import FLAT_PATCH_OPTIONS

    docs = (ROOT / "docs" / "refiners.md").read_text()
    registry = get_plugin_manager(autoload=False).registry
    declared = {name: refiner.options for name, refiner, _ in registry.items("refiner")}
    declared["flat-patch"] = FLAT_PATCH_OPTIONS
    for name, options in declared.items():
        assert f"<!-- options of {name} -->\n{table(options)}\n<!-- end -->" in docs, f"docs/refiners.md: the options table of {name!r} is not the one it declares"


# -- fuzz: whatever a template or recipe gives a step, the answer is a located RecipeError or a plan

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-10, 10**6) | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=8,
)
_KEYS = st.sampled_from(["width", "margin", "min_spacing", "clearance", "front_wall", "front_drop", "body_clearance", "rows", "widht", "step"]) | st.text(max_size=10)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(_KEYS, _VALUES, max_size=4))
def test_fuzzed_step_options_give_a_located_error_or_a_plan(options):
    import yaml

    from seatkit.template.engine import YamlTemplate

    entry = {"step": "border", **{k: v for k, v in options.items() if k != "step"}}
    text = STOOL.replace("  - step: border\n    width: 0.04                 # m\n", yaml.safe_dump([entry], default_flow_style=False).replace("- ", "  - ", 1).replace("\n  ", "\n    ").rstrip() + "\n")
    try:
        t = load_template(text=text, source="fuzz.yaml")
        t = t.bind(BUILTIN_STEPS)
    except RecipeError as e:
        assert str(e).startswith("fuzz.yaml"), str(e)
        return
    assert isinstance(t, YamlTemplate)
    # the same values as a recipe override: a ParamError with its key path, or accepted
    from seatkit.errors import ParamError

    try:
        t.check_params({"steps": {"border": {k: v for k, v in options.items() if k != "step"}}})
    except ParamError as e:
        assert e.path[:2] == ("steps", "border")


def test_seatkit_pressure_uses_the_registry_and_its_backend_flag_is_not_a_solver(tmp_path):
    from typer.testing import CliRunner

    from seatkit.cli import app

    runner = CliRunner()
    done = runner.invoke(app, ["pressure", "--solver", "newton", "--out", str(tmp_path / "a")])
    assert done.exit_code == 1
    assert "unknown pressure solver 'newton'; available: qp" in done.output and "Traceback" not in done.output
    done = runner.invoke(app, ["pressure", "--backend", "newton", "--body", "default-female", "--mass", "60", "--out", str(tmp_path / "b")])
    assert done.exit_code == 0, done.output
    # the qp solver of the registry, with its backend option, on the registry's body model
    assert "default-female:upright-sitting" in done.output and "newton" in done.output
    assert "(weight 588.60 N)" in done.output and "total reaction 588.60 N" in done.output
    assert (tmp_path / "b" / "pressure.npz").is_file()
    done = runner.invoke(app, ["--disable-plugin", "qp", "pressure", "--out", str(tmp_path / "c")])
    assert done.exit_code == 1 and "(disabled plugins: qp)" in done.output
