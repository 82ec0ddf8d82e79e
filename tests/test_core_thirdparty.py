"""The documented third-party plugin example really installs and shows up."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "seatkit-stool-plugin"


def _pip_install(target, project, dist):
    """``pip install --target`` an example plugin; the folder to put on PYTHONPATH."""
    cmd = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--target", str(target), str(project)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert list(target.glob(f"{dist}-*.dist-info"))
    return target


@pytest.fixture(scope="module")
def installed_example(tmp_path_factory):
    return _pip_install(tmp_path_factory.mktemp("site"), EXAMPLE, "seatkit_stool")


def run_seatkit(site, *args):
    env = dict(os.environ)
    env.pop("SEATKIT_DISABLE_PLUGIN_AUTOLOAD", None)  # this test is about autoloading
    env["PYTHONPATH"] = os.pathsep.join([str(site), env.get("PYTHONPATH", "")])
    code = "import sys; from seatkit.cli import main; sys.argv = ['seatkit', *sys.argv[1:]]; main()"
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=env)


def test_example_plugin_is_listed_by_plugins_and_templates(installed_example):
    plugins = run_seatkit(installed_example, "plugins")
    assert plugins.returncode == 0, plugins.stderr
    line = next(l for l in plugins.stdout.splitlines() if l.strip().startswith("stool"))
    assert "seatkit-stool" in line and "0.1.0" in line and "template: stool" in line
    templates = run_seatkit(installed_example, "templates")
    assert templates.returncode == 0, templates.stderr
    # columns template, description (wrapped), plugin: the row's first line names both
    assert any(l.split()[:1] == ["stool"] and l.split()[-1] == "stool" for l in templates.stdout.splitlines())


def test_autoload_switch_hides_the_example(installed_example):
    env_flag = {"SEATKIT_DISABLE_PLUGIN_AUTOLOAD": "1"}
    os.environ.update(env_flag)
    try:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(installed_example), env.get("PYTHONPATH", "")])
        code = "import sys; from seatkit.cli import main; sys.argv = ['seatkit', 'templates']; main()"
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    finally:
        os.environ["SEATKIT_DISABLE_PLUGIN_AUTOLOAD"] = "1"
    assert done.returncode == 0, done.stderr
    assert not any(l.startswith("stool") for l in done.stdout.splitlines())


def test_disable_plugin_flag_hides_the_example(installed_example):
    done = run_seatkit(installed_example, "--disable-plugin", "stool", "templates")
    assert done.returncode == 0, done.stderr
    assert not any(l.startswith("stool") for l in done.stdout.splitlines())


def test_example_template_fits_the_default_body():
    import importlib.util

    from seatkit.body import load_pose, load_rig, pose_rig
    from seatkit.plugins import get_plugin_manager

    spec = importlib.util.spec_from_file_location("seatkit_stool", EXAMPLE / "seatkit_stool" / "__init__.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    pm = get_plugin_manager(autoload=False)
    pm.register_plugin(module, "stool")
    stool = pm.registry.get("template", "stool")
    body = pose_rig(load_rig("default-male"), load_pose("upright-sitting"))
    pressure = pm.registry.get("pressure_solver", "qp").solve(body)
    mesh = stool.fit([body], [pressure], seed=0)
    assert mesh.faces.shape == ((2 + 4) * (3 + 4), 4)
    assert {"thigh.left", "thigh.right", "shank.left", "shank.right"} <= set(mesh.face_labels)


LEVEL = ROOT / "examples" / "seatkit-level-plugin"


@pytest.fixture(scope="module")
def installed_level(tmp_path_factory):
    return _pip_install(tmp_path_factory.mktemp("site-level"), LEVEL, "seatkit_level")


def test_python_step_example_is_installed_and_builds(installed_level, tmp_path):
    import json

    plugins = run_seatkit(installed_level, "plugins")
    assert plugins.returncode == 0, plugins.stderr
    # the table wraps to the terminal: a row's components may continue on lines whose first cell is blank
    lines = plugins.stdout.splitlines()
    start = next(i for i, l in enumerate(lines) if l.strip().startswith("level"))
    row = [lines[start]]
    for l in lines[start + 1:]:
        if "│" not in l or l.split("│")[0].strip():
            break
        row.append(l)
    cells = [[c.strip() for c in l.split("│")] for l in row]
    components = " ".join(c[-1] for c in cells if c[-1])
    assert cells[0][1] == "seatkit-level"
    assert "template step: level-rows" in components and "template: level-stool" in components
    recipe = tmp_path / "recipe.yaml"
    recipe.write_text(
        "template: level-stool\nrefiners: []\nexporters: [obj]\nevaluate: {enabled: false}\n"
        "template_params:\n  steps:\n    level-rows: {max_change: 0.1}\n"
    )
    out = tmp_path / "out"
    done = run_seatkit(installed_level, "build", "--recipe", str(recipe), "--out", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    meta = json.loads((out / "report.json").read_text())["control_mesh"]["meta"]
    assert meta["level-rows"]["rows"] == ["thigh"] and 0.0 <= meta["level-rows"]["largest_change_m"] <= 0.1
    # the levelled vertex lines (the thigh row's two lines; the border adds two rings) stay level
    # up to what the clearance step moved afterwards
    import numpy as np
    import trimesh

    cage = trimesh.load(out / "cage.obj", process=False)
    V = np.asarray(cage.vertices).reshape(2 + 5, 3 + 5, 3)
    for b in (3, 4):  # the thigh row's vertex lines, inside the rings
        spread = np.ptp(V[b, 2:-2, 1])
        assert spread <= meta["clearance"]["max_move"] + 1e-9
    # the same step from the disabled plugin: refused, one line
    done = run_seatkit(installed_level, "--disable-plugin", "level", "build", "--recipe", str(recipe), "--out", str(out))
    assert done.returncode == 1
    err = done.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("seatkit: error: ") and "unknown template 'level-stool'" in err[0]
    assert "(disabled plugins: level)" in err[0]
    # a name that is no plugin is refused, listing the names
    done = run_seatkit(installed_level, "--disable-plugin", "levle", "templates")
    assert done.returncode == 1
    assert "no such plugin; did you mean 'level'?" in done.stderr and "the plugins are: " in done.stderr


def test_an_uninstalled_checkout_says_what_failed_to_import(tmp_path):
    # the checkout on the path, its dependencies too, but not its installation (no site: no .pth finder)
    # the dependencies without seatkit's own installed copy (a non-editable
    # install puts seatkit and its built-in plugins in site-packages too)
    deps = tmp_path / "deps"
    deps.mkdir()
    for site in (Path(p) for p in sys.path if p.endswith("site-packages")):
        for entry in site.iterdir():
            if not entry.name.lower().startswith("seatkit") and not (deps / entry.name).exists():
                (deps / entry.name).symlink_to(entry)
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(deps)])
    code = "import sys; from seatkit.cli import main; sys.argv = ['seatkit', 'build', '--template', 'chair']; main()"
    done = subprocess.run([sys.executable, "-S", "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("seatkit: error: template: unknown template 'chair'; available: none; ")
    assert "this checkout is not installed; run pip install -e . in it" in last
    assert "ModuleNotFoundError: No module named 'seatkit_bodies'" in last
    assert "Traceback" not in done.stderr


RELAX = ROOT / "examples" / "seatkit-relax-plugin"


@pytest.fixture(scope="module")
def installed_relax(tmp_path_factory):
    return _pip_install(tmp_path_factory.mktemp("site-relax"), RELAX, "seatkit_relax")


def test_refiner_and_exporter_example_is_installed_and_builds(installed_relax, tmp_path):
    import json
    import xml.etree.ElementTree as ET

    import numpy as np
    import trimesh

    plugins = run_seatkit(installed_relax, "plugins")
    assert plugins.returncode == 0, plugins.stderr
    assert "seatkit-relax" in plugins.stdout and "refiner: relax" in plugins.stdout and "exporter: profile-svg" in plugins.stdout
    recipe = tmp_path / "recipe.yaml"
    recipe.write_text(
        "template: chair\n"
        "refiners: [optimize, {name: relax, params: {iterations: 3, max_move: 0.015}}]\n"
        "exporters: [obj, {name: profile-svg, params: {view: side, scale: 250}}]\n"
        "evaluate: {enabled: false}\n"
    )
    out = tmp_path / "out"
    done = run_seatkit(installed_relax, "build", "--recipe", str(recipe), "--out", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    report = json.loads((out / "report.json").read_text())
    relax = report["control_mesh"]["meta"]["relax"]
    assert relax["params"] == {"iterations": 3, "weight": 0.5, "max_move": 0.015}  # the given ones and the declared default
    assert 0.0 < relax["largest_move_m"] <= 0.015 + 1e-12
    cage = trimesh.load(out / "cage.obj", process=False)
    V = np.asarray(cage.vertices)
    ground = np.isclose(V[:, 1], 0.0, atol=1e-6)
    assert ground.sum() >= 20  # the border ring is still on the floor (the refiner check holds it there)
    # the drawing: one line per cage edge, the ground ring on the floor line, 250 px per metre
    svg = ET.parse(out / "profile-side.svg").getroot()
    ns = "{http://www.w3.org/2000/svg}"
    edges = [l for l in svg.iter(f"{ns}line") if l.get("class") == "edge"]
    (floor,) = [l for l in svg.iter(f"{ns}line") if l.get("class") == "floor"]
    quads = np.array([[int(t.split("/")[0]) - 1 for t in line.split()[1:]] for line in (out / "cage.obj").read_text().splitlines() if line.startswith("f ")])
    assert quads.shape[1] == 4
    n_edges = len(np.unique(np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], -1).reshape(-1, 2), axis=1), axis=0))
    assert len(edges) == n_edges == len(V) + len(quads) - 1  # a disc: V - E + F = 1
    ys = np.array([[float(l.get("y1")), float(l.get("y2"))] for l in edges]).ravel()
    assert np.isclose(ys.max() - float(floor.get("y1")), -250 * min(V[:, 1].min(), 0.0), atol=0.02)  # the floor line at y = 0
    assert np.isclose(np.ptp(ys), 250 * np.ptp(V[:, 1]), rtol=1e-3)
    xs = np.array([[float(l.get("x1")), float(l.get("x2"))] for l in edges]).ravel()
    assert np.isclose(np.ptp(xs), 250 * np.ptp(V[:, 2]), rtol=1e-3)
    # a misspelt option of each: one line with the file's line and "did you mean", before any geometry
    recipe.write_text(
        "template: chair\n"
        "refiners: [optimize, {name: relax, params: {iteratons: 3}}]\n"
    )
    done = run_seatkit(installed_relax, "build", "--recipe", str(recipe), "--out", str(out))
    assert done.returncode == 1
    assert done.stderr.strip() == (
        f"seatkit: error: {recipe}:2: refiners[1].params.iteratons: refiner 'relax' has no option 'iteratons'; "
        "its options are: iterations, max_move, weight; did you mean 'iterations'?"
    )
    recipe.write_text("template: chair\nexporters:\n  - name: profile-svg\n    params: {view: sied}\n")
    done = run_seatkit(installed_relax, "build", "--recipe", str(recipe), "--out", str(out))
    assert done.returncode == 1
    assert done.stderr.strip() == (
        f"seatkit: error: {recipe}:4: exporters[0].params.view: expected one of side, front, top, got 'sied'; did you mean 'side'?"
    )
