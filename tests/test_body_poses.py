"""Pose YAML files and the shipped pose library."""

import textwrap

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from seatkit.body import list_poses, load_pose, load_pose_file, load_rig, pose_rig
from seatkit.body.poses import euler_to_rotvec
from seatkit.errors import RecipeError
from seatkit.model import Pose
from seatkit.skeleton import SEGMENT_INDEX

LIBRARY = {
    "upright-sitting", "reclined-sitting", "armrest-sitting", "crossed-legs-ankles", "crossed-legs-knees",
    "leaning-forward", "lounger", "lying-supine", "standing-leaning-back", "lying-side", "feet-tucked",
}
SEATED = ["upright-sitting", "reclined-sitting", "armrest-sitting", "crossed-legs-ankles", "crossed-legs-knees", "leaning-forward"]


@pytest.fixture(scope="module")
def rig():
    return load_rig("default-male")


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_library_contents():
    infos = {p.name: p for p in list_poses()}
    assert LIBRARY <= set(infos)
    assert {n for n, p in infos.items() if not p.supported} >= {"lying-side", "feet-tucked"}
    for info in infos.values():
        assert info.description and "\n" not in info.description
        assert info.path.is_file()


@pytest.mark.parametrize("name", sorted(LIBRARY))
@pytest.mark.parametrize("body", ["default-male", "default-female"])
def test_every_library_pose_is_finite_and_on_the_ground(name, body):
    rig = load_rig(body)
    posed = pose_rig(rig, load_pose(name))
    assert np.isfinite(posed.vertices).all()
    assert posed.vertices[:, 1].min() == pytest.approx(0.0, abs=1e-12)
    assert (posed.segment_com[:, 1] > 0).all()


@pytest.mark.parametrize("name", SEATED)
def test_seated_poses_look_seated(rig, name):
    body = pose_rig(rig, load_pose(name))
    j = {n: body.joints[i] for n, i in SEGMENT_INDEX.items()}
    # hips at chair height, the trunk above them
    assert 0.40 < j["Hips"][1] < 0.55
    assert j["Spine3"][1] > j["Hips"][1] + 0.3
    for side in ("Left", "Right"):
        thigh = j[side + "Leg"] - j[side + "UpLeg"]
        assert thigh[2] > 0.3  # thighs point forward
    left_thigh = j["LeftLeg"] - j["LeftUpLeg"]
    assert abs(np.degrees(np.arctan2(left_thigh[1], left_thigh[2]))) < 25  # roughly horizontal
    # at least one foot on the ground
    feet = body.weights[:, [SEGMENT_INDEX["LeftFoot"], SEGMENT_INDEX["RightFoot"]]].sum(axis=1) > 0.5
    assert body.vertices[feet, 1].min() < 1e-9


def test_upright_sitting_knees_at_90_degrees(rig):
    body = pose_rig(rig, load_pose("upright-sitting"))
    for side in ("Left", "Right"):
        thigh = body.tips[SEGMENT_INDEX[side + "UpLeg"]] - body.joints[SEGMENT_INDEX[side + "UpLeg"]]
        shin = body.tips[SEGMENT_INDEX[side + "Leg"]] - body.joints[SEGMENT_INDEX[side + "Leg"]]
        angle = np.degrees(np.arccos(thigh @ shin / np.linalg.norm(thigh) / np.linalg.norm(shin)))
        assert 80 < angle < 100


def test_euler_convention_is_intrinsic_xyz(tmp_path):
    path = write(tmp_path, "p.yaml", """
        joints:
          RightArm: {x: 10, y: 20, z: 30}
    """)
    pose = load_pose(path)
    R = Rotation.from_rotvec(pose.rotations[SEGMENT_INDEX["RightArm"]]).as_matrix()
    def rx(a): return Rotation.from_euler("x", a, degrees=True).as_matrix()
    def ry(a): return Rotation.from_euler("y", a, degrees=True).as_matrix()
    def rz(a): return Rotation.from_euler("z", a, degrees=True).as_matrix()
    # intrinsic X then Y then Z: R = Rx Ry Rz
    np.testing.assert_allclose(R, rx(10) @ ry(20) @ rz(30), atol=1e-12)
    np.testing.assert_allclose(euler_to_rotvec([[0, 0, 90]])[0], [0, 0, np.pi / 2])


def test_hip_flexion_sign(rig, tmp_path):
    # x: -90 on an UpLeg swings the thigh forwards (+Z), as the docs say
    path = write(tmp_path, "p.yaml", "joints:\n  LeftUpLeg: {x: -90}\n")
    body = pose_rig(rig, load_pose(path), ground=False)
    i = SEGMENT_INDEX["LeftUpLeg"]
    d = body.tips[i] - body.joints[i]
    assert d[2] > 0.95 * np.linalg.norm(d)


def test_base_and_override(tmp_path):
    write(tmp_path, "a.yaml", """
        description: base
        joints:
          RightLeg: {x: 90}
          LeftLeg: {x: 45, y: 5}
        root:
          translation: [0, 0.1, 0]
    """)
    b = write(tmp_path, "b.yaml", """
        base: a.yaml
        joints:
          LeftLeg: {x: 30}
        root:
          rotation: {y: 90}
    """)
    spec = load_pose_file(b)
    np.testing.assert_allclose(spec.angles[SEGMENT_INDEX["RightLeg"]], [90, 0, 0])
    np.testing.assert_allclose(spec.angles[SEGMENT_INDEX["LeftLeg"]], [30, 0, 0])  # replaced whole
    np.testing.assert_allclose(spec.angles[0], [0, 90, 0])
    np.testing.assert_allclose(spec.root_translation, [0, 0.1, 0])
    assert spec.supported is True


def test_library_base(tmp_path):
    path = write(tmp_path, "c.yaml", "base: upright-sitting\njoints:\n  Head: {x: 10}\n")
    pose = load_pose(path)
    upright = load_pose("upright-sitting")
    same = [i for i in range(21) if i != SEGMENT_INDEX["Head"]]
    np.testing.assert_allclose(pose.rotations[same], upright.rotations[same])


def test_pose_object_passes_through():
    p = Pose.rest()
    assert load_pose(p) is p


@pytest.mark.parametrize(
    "text, line, pattern",
    [
        ("joints:\n  RightThigh: {x: 10}\n", 2, r"joints\.RightThigh: unknown joint; expected one of Hips"),
        ("joints:\n  RightLeg: {x: ten}\n", 2, r"joints\.RightLeg\.x: expected an angle in degrees from -720 to 720, got 'ten'"),
        ("joints:\n  RightLeg:\n    w: 3\n", 3, r"joints\.RightLeg\.w: unknown axis"),
        ("joints:\n  RightLeg: 90\n", 2, r"joints\.RightLeg: expected a mapping"),
        ("base: no-such-pose\n", 1, r"base: unknown pose 'no-such-pose'"),
        ("descripton: x\n", 1, r"descripton: unknown key"),
        ("supported: maybe\n", 1, r"supported: expected true or false"),
        ("root:\n  translation: [0, 1]\n", 2, r"root\.translation: expected \[x, y, z\]"),
        ("root:\n  translation: [0, a, 1]\n", 2, r"root\.translation\[1\]: expected a number"),
        ("joints:\n  Hips: {x: 3}\n", 2, r"joints\.Hips: the root segment is posed under root\.rotation"),
        ("joints: [1, 2\n", 2, r"not valid YAML"),
    ],
)
def test_yaml_errors_name_file_line_and_key(tmp_path, text, line, pattern):
    path = write(tmp_path, "bad.yaml", text)
    with pytest.raises(RecipeError, match=pattern) as e:
        load_pose(path)
    assert str(e.value).startswith(f"{path}:{line}:")


def test_base_cycle(tmp_path):
    write(tmp_path, "a.yaml", "base: b.yaml\n")
    write(tmp_path, "b.yaml", "base: a.yaml\n")
    with pytest.raises(RecipeError, match=r"b.yaml:1: base: cycle of base poses \(a -> b -> a\)"):
        load_pose(tmp_path / "a.yaml")


def test_unknown_library_name():
    with pytest.raises(RecipeError, match="unknown pose 'dancing'.*upright-sitting"):
        load_pose("dancing")
