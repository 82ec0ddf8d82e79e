"""The documented third-party plugin example really installs and shows up."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "seatkit-stool-plugin"


@pytest.fixture(scope="module")
def installed_example(tmp_path_factory):
    target = tmp_path_factory.mktemp("site")
    cmd = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--target", str(target), str(EXAMPLE)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert list(target.glob("seatkit_stool-*.dist-info"))
    return target


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
