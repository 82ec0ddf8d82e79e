"""Suite-wide settings and shared fixtures.

Entry-point autoloading is switched off, so third-party plugins installed on
the machine cannot change results; built-in plugins are still registered.
Matplotlib draws off-screen.
"""

import os

import pytest

os.environ["SEATKIT_DISABLE_PLUGIN_AUTOLOAD"] = "1"
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="session")
def seated():
    """The default male body in every supportable library pose, with pressure.

    A dict pose name -> (Body, PressureField); shared by the refiner tests.
    """
    from seatkit.body import list_poses, load_pose, load_rig, pose_rig
    from seatkit.pressure import solve_pressure

    rig = load_rig("default-male", mass=75.0)
    out = {}
    for info in list_poses():
        if info.supported:
            body = pose_rig(rig, load_pose(info.name), ground=True)
            out[info.name] = (body, solve_pressure(body))
    return out


@pytest.fixture(scope="session")
def p50_upright_design(tmp_path_factory):
    """A p50-male upright chair, built and written (design.npz, report.json): the design trials sit on."""
    from seatkit import build

    out = tmp_path_factory.mktemp("design") / "p50m"
    recipe = {
        "template": "chair",
        "bodies": [{"model": "p50-male", "pose": "upright-sitting"}],
        "output": str(out),
        "exporters": ["design", "report-json"],
        "evaluate": {"baseline": None},
    }
    build(recipe, processes=False)
    return out
