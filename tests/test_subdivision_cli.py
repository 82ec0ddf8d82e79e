"""``seatkit subdivide`` on OBJ and USD cages."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import trimesh
import typer
from typer.testing import CliRunner

from seatkit.commands.subdivide import register
from seatkit.export.meshes import write_cage_obj
from seatkit.export.usd import write_usd
from seatkit.subdivision import Cage, build_operators

_spec = importlib.util.spec_from_file_location(
    "seatkit_tests_osd_fixtures", Path(__file__).parent / "osd_reference" / "fixtures.py"
)
_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_fixtures)
runner = _fixtures.load_runner()


@pytest.fixture(scope="module")
def app():
    app = typer.Typer()
    register(app)

    @app.command()
    def _unused() -> None:  # a second command keeps typer in multi-command mode
        pass

    return app


def _obj_vertices(path):
    return np.array([[float(x) for x in s.split()[1:4]] for s in path.read_text().splitlines() if s.startswith("v ")])


def _creased_cage():
    v, f, crease = runner.chair_cage()
    return Cage(v, f, crease_edges=crease, crease_sharpness=[2.3] * len(crease), corners=[0], corner_sharpness=[10.0])


def test_usd_cage_keeps_creases(tmp_path, app):
    cage = _creased_cage()
    usd = write_usd(tmp_path / "cage.usda", cage)
    out = tmp_path / "limit.obj"
    res = CliRunner().invoke(app, ["subdivide", str(usd), "--levels", "2", "--out", str(out), "--limit"])
    assert res.exit_code == 0, res.output
    assert "limit positions" in res.output
    np.testing.assert_allclose(_obj_vertices(out), build_operators(cage, 2).limit @ cage.vertices, atol=1e-6)


def test_obj_cage_refined_points(tmp_path, app):
    v, f = runner.mixed_cage()
    cage = Cage(v, f)
    obj = write_cage_obj(cage, tmp_path / "cage.obj")
    out = tmp_path / "refined.obj"
    res = CliRunner().invoke(app, ["subdivide", str(obj), "--levels", "3", "--out", str(out)])
    assert res.exit_code == 0, res.output
    ops = build_operators(cage, 3)
    np.testing.assert_allclose(_obj_vertices(out), ops.refine @ v, atol=1e-7)
    ply = tmp_path / "refined.ply"
    res = CliRunner().invoke(app, ["subdivide", str(obj), "-n", "1", "--out", str(ply), "--boundary", "edge-only"])
    assert res.exit_code == 0, res.output
    assert len(trimesh.load(ply, process=False).faces) == 2 * len(build_operators(cage, 1).faces)


def test_usd_output(tmp_path, app):
    from pxr import Usd, UsdGeom

    obj = write_cage_obj(Cage(*runner.cube_cage()), tmp_path / "cube.obj")
    out = tmp_path / "cube.usdc"
    res = CliRunner().invoke(app, ["subdivide", str(obj), "--levels", "2", "--out", str(out), "--limit"])
    assert res.exit_code == 0, res.output
    stage = Usd.Stage.Open(str(out))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/seatkit/Refined"))
    assert len(mesh.GetPointsAttr().Get()) == 98 and len(mesh.GetNormalsAttr().Get()) == 98


def test_bad_inputs_are_user_errors(tmp_path, app):
    from seatkit.errors import InputError

    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 1 0 1\nv nan 0 1\nf 1 2 3 4\n")
    res = CliRunner().invoke(app, ["subdivide", str(bad), "--out", str(tmp_path / "x.obj")])
    assert res.exit_code != 0 and isinstance(res.exception, InputError)
    assert "bad.obj:4: vertex 4: coordinates must be finite" in str(res.exception)  # the line, not only the file
    res = CliRunner().invoke(app, ["subdivide", str(bad), "--out", str(tmp_path / "x.xyz")])
    assert isinstance(res.exception, InputError) and "unknown format" in str(res.exception)
    assert not (tmp_path / "x.obj").exists()
