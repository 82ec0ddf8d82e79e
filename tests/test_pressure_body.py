"""The pressure QP on the shipped default body, its CLI and its plugin."""

from __future__ import annotations

import numpy as np
import pytest

from seatkit.body import list_poses, load_pose, load_rig, pose_rig
from seatkit.constants import GRAVITY
from seatkit.pressure import solve_pressure
from seatkit.pressure.assembly import body_geometry
from seatkit.skeleton import SEGMENT_INDEX

SEAT_SEGMENTS = [SEGMENT_INDEX[n] for n in ("Hips", "RightUpLeg", "LeftUpLeg", "RightFoot", "LeftFoot")]


@pytest.fixture(scope="module")
def rig():
    return load_rig("default-male")


@pytest.fixture(scope="module")
def seated(rig):
    return pose_rig(rig, load_pose("upright-sitting"))


def _owner(body):
    return np.argmax(body.weights, axis=1)


def test_default_exclusions_put_the_load_where_a_seat_carries_it(seated):
    field = solve_pressure(seated)
    weight = seated.mass * GRAVITY
    owner = _owner(seated)
    on_seat = field.force[np.isin(owner, SEAT_SEGMENTS), 1].sum() / weight
    assert on_seat > 0.75
    face = seated.region_labels["face"]
    assert np.abs(field.force[face]).max() == 0.0
    hands = seated.region_labels["hands"]
    assert np.abs(field.force[hands]).max() == 0.0
    # the highest pressures are under the buttocks, thighs and feet
    top = np.argsort(field.pressure)[-20:]
    assert np.isin(owner[top], SEAT_SEGMENTS).all()


def test_without_exclusions_the_face_carries_peaks(seated):
    """Why the defaults exist: the paper's model alone loads the face (measured-facts)."""
    field = solve_pressure(seated, exclude=[])
    top4 = np.argsort(field.pressure)[-4:]
    assert np.isin(top4, seated.region_labels["face"]).all()


def test_removing_the_feet_unloads_the_backrest(rig):
    """The paper's Figure 3: without the feet, the backrest loses (almost) all its load.

    Reclined sitting body; seat = the lowest 1.5 cm of pelvis and thighs,
    backrest = the 1.5 cm of trunk skin nearest a plane tilted 20 degrees back,
    floor = everything within 1.5 cm of y = 0.
    """
    body = pose_rig(rig, load_pose("reclined-sitting"))
    v, w = body.vertices, body.weights
    d = 0.015
    pelvis = w[:, [0, 1, 4]].sum(axis=1) > 0.5
    seat = pelvis & (v[:, 1] < v[pelvis, 1].min() + d)
    tilt = np.radians(20.0)
    along = v @ np.array([0.0, np.sin(tilt), np.cos(tilt)])
    trunk = w[:, [7, 8, 9, 10]].sum(axis=1) > 0.5
    back = trunk & (along < along[trunk].min() + d)
    floor = v[:, 1] < d
    with_feet = solve_pressure(body, contact=seat | back | floor, exclude=[])
    without = solve_pressure(body, contact=seat | back, exclude=[])
    back_with = np.linalg.norm(with_feet.force[back].sum(axis=0))
    back_without = np.linalg.norm(without.force[back].sum(axis=0))
    assert back_with > 0.1 * body.mass * GRAVITY  # the backrest does carry load with the feet down
    assert back_without <= 0.2 * back_with
    assert np.linalg.norm(without.joint_moment, axis=1).max() > np.linalg.norm(with_feet.joint_moment, axis=1).max()


@pytest.mark.parametrize("pose", [p.name for p in list_poses()])
def test_every_library_pose_is_in_equilibrium(rig, pose):
    body = pose_rig(rig, load_pose(pose))
    field = solve_pressure(body)
    weight = body.mass * GRAVITY
    assert abs(field.force[:, 1].sum() - weight) < 1e-6 * weight
    assert field.residuals["segment_force"] < 1e-6 and field.residuals["segment_moment"] < 1e-6
    assert field.residuals["min_normal_force"] >= -1e-9
    assert field.residuals["friction_excess"] <= 1e-9
    assert np.abs(field.force[body.region_labels["face"]]).max() == 0.0


def test_geometry_is_outward(seated):
    geo = body_geometry(seated.vertices, seated.faces)
    top = np.argmax(seated.vertices[:, 1])
    assert geo.normal[top, 1] > 0.9
    assert geo.area.min() > 0


def test_cli_writes_npz_ply_png(tmp_path):
    import typer
    from typer.testing import CliRunner

    from seatkit.commands.pressure import register
    from seatkit.pressure.field import NPZ_KEYS

    app = typer.Typer()
    register(app)

    @app.command()
    def _other() -> None:  # a second command keeps typer in sub-command mode
        pass

    result = CliRunner().invoke(app, ["pressure", "--pose", "upright-sitting", "--out", str(tmp_path), "--mu", "0.4"])
    assert result.exit_code == 0, result.output
    data = np.load(tmp_path / "pressure.npz")
    assert set(NPZ_KEYS) <= set(data.files)
    n = len(data["vertices"])
    assert data["force"].shape == (n, 3) and data["pressure"].shape == (n,) and data["contact"].dtype == bool
    assert data["joint_moment"].shape == (20, 3) and data["segment_com"].shape == (21, 3)
    assert float(data["mu"]) == 0.4
    assert abs(data["force"][:, 1].sum() - data["segment_mass"].sum() * GRAVITY) < 1e-6 * 735.75
    ply = (tmp_path / "pressure.ply").read_bytes()
    assert ply.startswith(b"ply\n") and f"element vertex {n}".encode() in ply
    assert (tmp_path / "pressure.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plugin_registers_the_qp_solver():
    import seatkit_qp

    from seatkit.interfaces import PressureSolver

    (solver,) = seatkit_qp.seatkit_register_pressure_solvers()
    assert isinstance(solver, PressureSolver)
    assert solver.name == "qp"


def test_body_geometry_kept_for_a_body_is_the_geometry_computed_anew(seated):
    """The areas and normals kept for a body's arrays are those computed anew, each call's own copy; other vertices get their own."""
    from seatkit.geometry.normals import vertex_normals
    from seatkit.pressure.areas import mixed_voronoi_areas

    body = seated
    first, again = body_geometry(body.vertices, body.faces), body_geometry(body.vertices, body.faces)
    assert np.array_equal(first.area, mixed_voronoi_areas(body.vertices, body.faces))
    assert np.array_equal(first.normal, vertex_normals(body.vertices, body.faces))
    assert np.array_equal(again.area, first.area) and np.array_equal(again.normal, first.normal)
    again.area[:] = 0.0  # a caller's copy: what the next call gets is untouched
    assert np.array_equal(body_geometry(body.vertices, body.faces).area, first.area)
    stretched = body.vertices * [1.0, 1.1, 1.0]
    other = body_geometry(stretched, body.faces)
    assert np.array_equal(other.area, mixed_voronoi_areas(stretched, body.faces)) and not np.array_equal(other.area, first.area)


def test_kept_vertex_normals_are_the_normals_computed_anew_and_read_only(seated):
    from seatkit.geometry.normals import kept_vertex_normals, vertex_normals

    kept = kept_vertex_normals(seated.vertices, seated.faces)
    assert kept is kept_vertex_normals(seated.vertices, seated.faces)
    assert np.array_equal(kept, vertex_normals(seated.vertices, seated.faces))
    with pytest.raises(ValueError):
        kept[0, 0] = 1.0
    moved = seated.vertices + [0.0, 0.0, 0.5]  # other arrays, their own normals (the same here: a translation)
    assert kept_vertex_normals(moved, seated.faces) is not kept
