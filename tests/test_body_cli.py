"""``seatkit body`` and ``seatkit poses``."""

import numpy as np
import trimesh
from typer.testing import CliRunner

from seatkit.body import load_pose, load_rig, pose_rig
from seatkit.cli import app

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, list(args), catch_exceptions=False)


def test_poses_lists_library_with_support():
    result = invoke("poses")
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    for name in ("upright-sitting", "lounger", "lying-side", "feet-tucked"):
        assert any(line.startswith(name) for line in lines), name
    line = next(line for line in lines if line.startswith("lying-side"))
    assert " no " in line
    line = next(line for line in lines if line.startswith("upright-sitting"))
    assert " yes " in line


def test_body_writes_ply_and_png(tmp_path):
    out, png = tmp_path / "body.ply", tmp_path / "body.png"
    result = invoke("body", "--pose", "reclined-sitting", "--out", str(out), "--png", str(png), "--body", "default-female", "--mass", "60")
    assert result.exit_code == 0, result.output
    mesh = trimesh.load(out, process=False)
    expected = pose_rig(load_rig("default-female", mass=60), load_pose("reclined-sitting"))
    np.testing.assert_allclose(mesh.vertices, expected.vertices, atol=1e-6)
    assert mesh.faces.shape == expected.faces.shape
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "60.0 kg" in result.output


def test_body_from_pose_file_and_rig_file(tmp_path):
    from seatkit.body import save_rig

    rig_path = save_rig(load_rig("default-male"), tmp_path / "me.npz")
    pose = tmp_path / "p.yaml"
    pose.write_text("joints:\n  LeftArm: {z: -80}\n")
    out = tmp_path / "b.obj"
    result = invoke("body", "--pose", str(pose), "--out", str(out), "--body", str(rig_path))
    assert result.exit_code == 0, result.output
    assert out.stat().st_size > 100_000


def test_body_user_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("joints:\n  LeftElbow: {x: 1}\n")
    result = runner.invoke(app, ["body", "--pose", str(bad), "--out", str(tmp_path / "b.ply")])
    assert result.exit_code == 1
    assert f"{bad}:2: joints.LeftElbow: unknown joint" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "b.ply").exists()
    result = runner.invoke(app, ["body", "--pose", "upright-sitting", "--out", str(tmp_path / "b.xyz")])
    assert result.exit_code == 1 and "unknown mesh format" in result.output
