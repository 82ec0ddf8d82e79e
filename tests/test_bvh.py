"""BVH import and export (seatkit.body.bvh)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from seatkit.body.bvh import detect_unit, load_bvh, read_bvh, write_bvh
from seatkit.body.name_maps import candidate_maps, choose_map
from seatkit.body.rig import default_body_path, make_rig
from seatkit.body.skinning import forward_kinematics, pose_rig
from seatkit.errors import InputError
from seatkit.model import Pose
from seatkit.skeleton import N_SEGMENTS, PARENTS, SEGMENT_INDEX as I

DEFAULT_READY = default_body_path("default-male").is_file()


def _tpose(arm_drop_deg: float = 0.0):
    """Joints and tips of a small T-pose skeleton (arms dropped by an angle for an A-pose)."""
    j = np.zeros((N_SEGMENTS, 3))
    tips = np.zeros((N_SEGMENTS, 3))
    j[I["Hips"]] = [0, 1.0, 0]
    for side, x in (("Right", -0.09), ("Left", 0.09)):
        j[I[side + "UpLeg"]] = [x, 0.95, 0]
        j[I[side + "Leg"]] = [x, 0.52, 0.01]
        j[I[side + "Foot"]] = [x, 0.08, 0]
        tips[I[side + "Foot"]] = [x, 0.02, 0.16]
    for k, name in enumerate(["Spine", "Spine1", "Spine2", "Spine3"]):
        j[I[name]] = [0, 1.08 + 0.1 * k, -0.01 * k]
    j[I["Neck"]] = [0, 1.50, 0]
    j[I["Head"]] = [0, 1.58, 0.01]
    tips[I["Head"]] = [0, 1.80, 0.02]
    drop = np.radians(arm_drop_deg)
    for side, sg in (("Right", -1), ("Left", 1)):
        j[I[side + "Shoulder"]] = [sg * 0.03, 1.45, 0]
        shoulder = np.array([sg * 0.18, 1.45, 0])
        j[I[side + "Arm"]] = shoulder
        for name, reach in (("ForeArm", 0.28), ("Hand", 0.54)):
            j[I[side + name]] = shoulder + reach * np.array([sg * np.cos(drop), -np.sin(drop), 0])
        tips[I[side + "Hand"]] = shoulder + 0.72 * np.array([sg * np.cos(drop), -np.sin(drop), 0])
    chain = {0: I["Spine"], I["Spine3"]: I["Neck"]}
    for s in range(N_SEGMENTS):
        kids = np.flatnonzero(PARENTS == s)
        if len(kids):
            tips[s] = j[chain.get(s, kids[0])]
    return j, tips


def synthetic_rig(arm_drop_deg: float = 0.0, rotate=None):
    """A rig of one box per segment (8 vertices each, rigid weights)."""
    joints, tips = _tpose(arm_drop_deg)
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    tri = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                    [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    lo = np.minimum(joints, tips) - 0.03
    hi = np.maximum(joints, tips) + 0.03
    vertices = (lo[:, None, :] + cube[None] * (hi - lo)[:, None, :]).reshape(-1, 3)
    faces = (tri[None] + 8 * np.arange(N_SEGMENTS)[:, None, None]).reshape(-1, 3)
    weights = np.repeat(np.eye(N_SEGMENTS), 8, axis=0)
    if rotate is not None:
        vertices, joints, tips = vertices @ rotate.T, joints @ rotate.T, tips @ rotate.T
    return make_rig(vertices, faces, weights, joints, tips, name="synthetic")


def random_pose(seed: int = 0, scale: float = 0.6) -> Pose:
    rng = np.random.default_rng(seed)
    rot = rng.normal(size=(N_SEGMENTS, 3)) * scale
    rot[I["RightUpLeg"]] = [-np.pi / 2, 0, 0]  # a gimbal-lock angle for the YXZ channels
    return Pose(rot, np.zeros(3), "random")


@pytest.fixture(scope="module")
def rig():
    return synthetic_rig()


def test_round_trip_perception_neuron_synthetic(rig, tmp_path):
    pose = random_pose()
    path = write_bvh(tmp_path / "p.bvh", pose, rig)
    loaded = load_bvh(path, rig=rig)
    a, b = pose_rig(rig, pose), pose_rig(rig, loaded)
    assert np.abs(a.vertices - b.vertices).max() < 1e-9
    assert np.abs(a.joints - b.joints).max() < 1e-9
    assert loaded.name == "p.bvh#0"
    assert np.array_equal(loaded.translation, np.zeros(3))


@pytest.mark.skipif(not DEFAULT_READY, reason="default body not built yet")
def test_yaml_pose_reproduced_by_bvh_on_default_body(tmp_path):
    """The issue's test: a Perception Neuron BVH reproduces the YAML pose to 1e-6 m."""
    from seatkit.body import load_rig
    from seatkit.body.poses import load_pose

    body_rig = load_rig("default-male")
    yaml_path = tmp_path / "tilted.yaml"
    yaml_path.write_text(
        "description: test pose\n"
        "base: upright-sitting\n"
        "joints:\n"
        "  Spine1: {x: 12, y: -8, z: 5}\n"
        "  Neck: {x: 20, z: -10}\n"
        "  LeftArm: {x: -30, y: 25, z: -60}\n"
        "  RightForeArm: {y: 70}\n"
        "  LeftUpLeg: {x: -80, y: 15, z: 10}\n"
        "  RightFoot: {x: 20}\n"
        "root:\n"
        "  rotation: {x: -10, y: 20}\n",
        encoding="utf-8",
    )
    for spec in ("upright-sitting", yaml_path):
        pose = load_pose(spec)
        bvh = write_bvh(tmp_path / "pose.bvh", [Pose.rest(), pose], body_rig, "perception-neuron")
        # through the body helper's resolver, as `--pose file.bvh --frame 1` does
        from_bvh = load_pose(bvh, frame=1, rig=body_rig)
        a, b = pose_rig(body_rig, pose), pose_rig(body_rig, from_bvh)
        assert np.abs(a.vertices - b.vertices).max() < 1e-6
        assert np.abs(a.joints - b.joints).max() < 1e-6
        assert np.isfinite(b.vertices).all()


@pytest.mark.parametrize("naming", ["cmu", "mixamo"])
def test_cmu_and_mixamo_naming_parse(rig, tmp_path, naming):
    pose = random_pose(3)
    rotations = pose.rotations.copy()
    rotations[I["Spine2"]] = 0.0  # these conventions have no joint for Spine2
    pose = Pose(rotations, np.zeros(3))
    path = write_bvh(tmp_path / f"{naming}.bvh", pose, rig, naming)
    motion = read_bvh(path)
    chosen, index = choose_map(motion.names, candidate_maps(None, ("perception-neuron", "cmu", "mixamo")))
    assert chosen.name == naming
    assert index[I["Spine2"]] == -1 and (np.delete(index, I["Spine2"]) >= 0).all()
    loaded = load_bvh(path, rig=rig)
    assert np.abs(pose_rig(rig, pose).vertices - pose_rig(rig, loaded).vertices).max() < 1e-9


CMU_TEXT = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT LHipJoint
  { OFFSET 0 0 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    JOINT LeftUpLeg
    { OFFSET 3.5 -3 0
      CHANNELS 3 Zrotation Yrotation Xrotation
      JOINT LeftLeg
      { OFFSET 0 -17 0
        CHANNELS 3 Zrotation Yrotation Xrotation
        JOINT LeftFoot
        { OFFSET 0 -17 0
          CHANNELS 3 Zrotation Yrotation Xrotation
          JOINT LeftToeBase
          { OFFSET 0 -1 5
            CHANNELS 3 Zrotation Yrotation Xrotation
            End Site
            { OFFSET 0 0 2 }
          }
        }
      }
    }
  }
  JOINT RHipJoint
  { OFFSET 0 0 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    JOINT RightUpLeg
    { OFFSET -3.5 -3 0
      CHANNELS 3 Zrotation Yrotation Xrotation
      JOINT RightLeg
      { OFFSET 0 -17 0
        CHANNELS 3 Zrotation Yrotation Xrotation
        JOINT RightFoot
        { OFFSET 0 -17 0
          CHANNELS 3 Zrotation Yrotation Xrotation
          End Site
          { OFFSET 0 -1 6 }
        }
      }
    }
  }
  JOINT LowerBack
  { OFFSET 0 1 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    JOINT Spine
    { OFFSET 0 4 0
      CHANNELS 3 Zrotation Yrotation Xrotation
      JOINT Spine1
      { OFFSET 0 4 0
        CHANNELS 3 Zrotation Yrotation Xrotation
        JOINT Neck
        { OFFSET 0 4 0
          CHANNELS 3 Zrotation Yrotation Xrotation
          JOINT Neck1
          { OFFSET 0 2 0
            CHANNELS 3 Zrotation Yrotation Xrotation
            JOINT Head
            { OFFSET 0 2 0
              CHANNELS 3 Zrotation Yrotation Xrotation
              End Site
              { OFFSET 0 4 0 }
            }
          }
        }
        JOINT LeftShoulder
        { OFFSET 1 2 0
          CHANNELS 3 Zrotation Yrotation Xrotation
          JOINT LeftArm
          { OFFSET 5 0 0
            CHANNELS 3 Zrotation Yrotation Xrotation
            JOINT LeftForeArm
            { OFFSET 11 0 0
              CHANNELS 3 Zrotation Yrotation Xrotation
              JOINT LeftHand
              { OFFSET 10 0 0
                CHANNELS 3 Zrotation Yrotation Xrotation
                JOINT LThumb
                { OFFSET 1 0 1
                  CHANNELS 3 Zrotation Yrotation Xrotation
                  End Site
                  { OFFSET 1 0 1 }
                }
              }
            }
          }
        }
        JOINT RightShoulder
        { OFFSET -1 2 0
          CHANNELS 3 Zrotation Yrotation Xrotation
          JOINT RightArm
          { OFFSET -5 0 0
            CHANNELS 3 Zrotation Yrotation Xrotation
            JOINT RightForeArm
            { OFFSET -11 0 0
              CHANNELS 3 Zrotation Yrotation Xrotation
              JOINT RightHand
              { OFFSET -10 0 0
                CHANNELS 3 Zrotation Yrotation Xrotation
                End Site
                { OFFSET -3 0 0 }
              }
            }
          }
        }
      }
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0083333
"""
# channel count: root 6 + 24 joints x 3
_N_CHANNELS = 6 + 24 * 3


def _cmu_file(tmp_path: Path, neck1_x: float = 0.0) -> Path:
    """The CMU-style file with two frames: Neck1 bent by ``neck1_x`` degrees, then the root moved."""
    path = tmp_path / "cmu.bvh"
    path.write_text(CMU_TEXT + ("0 " * _N_CHANNELS + "\n") * 2, encoding="utf-8")
    motion = read_bvh(path)
    row = np.zeros(_N_CHANNELS)
    k = motion.names.index("Neck1")
    row[motion.rotation_columns[k][2]] = neck1_x  # Xrotation, the third channel
    second = row.copy()
    second[:3] = [10.0, 2.0, -5.0]  # root moves 10 units along x (an inch-sized skeleton)
    rows = [" ".join(map(str, r)) for r in (row, second)]
    path.write_text(CMU_TEXT + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_cmu_hand_written_file_extra_joints_folded(rig, tmp_path):
    path = _cmu_file(tmp_path, neck1_x=40.0)
    motion = read_bvh(path)
    assert len(motion.names) == 25 and motion.n_frames == 2
    chosen, index = choose_map(motion.names, candidate_maps(None, ("perception-neuron", "cmu", "mixamo")))
    assert chosen.name == "cmu"
    pose = load_bvh(path, rig=rig, frame=0)
    # extra joint Neck1 (40 deg) is folded into Neck: the Neck bone points along
    # the BVH's posed Neck -> Head chord
    glob, pos = motion.global_transforms(0)
    chord = pos[motion.names.index("Head")] - pos[motion.names.index("Neck")]
    _, posed = forward_kinematics(rig.joints, pose)
    bone = posed[I["Head"]] - posed[I["Neck"]]
    assert np.allclose(bone / np.linalg.norm(bone), chord / np.linalg.norm(chord), atol=1e-9)
    assert np.linalg.norm(pose.rotations[I["Neck"]]) > np.radians(10)
    # every bone with a BVH counterpart points where the BVH's does (rest T-pose on both)
    for seg, a, b in (("LeftLeg", "LeftLeg", "LeftFoot"), ("RightArm", "RightArm", "RightForeArm")):
        d_rig = posed[I[b]] - posed[I[a]]
        d_bvh = pos[motion.names.index(b)] - pos[motion.names.index(a)]
        assert np.allclose(d_rig / np.linalg.norm(d_rig), d_bvh / np.linalg.norm(d_bvh), atol=1e-9), seg
    # root motion: 10 units along x in a ~45-unit skeleton -> inches
    assert detect_unit(motion) == "inch"
    moved = load_bvh(path, rig=rig, frame=1, root_motion=True)
    assert np.allclose(moved.translation, np.array([10.0, 2.0, -5.0]) * 0.0254)
    assert np.allclose(load_bvh(path, rig=rig, frame=1, root_motion=True, unit="cm").translation, [0.1, 0.02, -0.05])


def test_tpose_bvh_onto_apose_rig_keeps_bone_directions(tmp_path):
    """Rest-pose correction: a BVH with T-pose rest drives an A-pose rig's bones to the same directions."""
    tpose, apose = synthetic_rig(0.0), synthetic_rig(45.0)
    pose = random_pose(7, scale=0.4)
    path = write_bvh(tmp_path / "t.bvh", pose, tpose)
    loaded = load_bvh(path, rig=apose)
    _, p_t = forward_kinematics(tpose.joints, pose)
    _, p_a = forward_kinematics(apose.joints, loaded)
    g_t, _ = forward_kinematics(tpose.joints, pose)
    g_a, _ = forward_kinematics(apose.joints, loaded)
    for s in range(1, N_SEGMENTS):
        child = [c for c in np.flatnonzero(PARENTS == s)][:1]
        if child:
            c = child[0] if s != I["Spine3"] else I["Neck"]
            u, v = p_t[c] - p_t[s], p_a[c] - p_a[s]
            assert np.allclose(u / np.linalg.norm(u), v / np.linalg.norm(v), atol=1e-9)
    # hands keep their rest relation to the forearm: same world direction of the hand bone
    for side in ("Left", "Right"):
        h = I[side + "Hand"]
        u = g_t[h] @ (tpose.tips[h] - tpose.joints[h])
        v = g_a[h] @ (apose.tips[h] - apose.joints[h])
        assert np.allclose(u / np.linalg.norm(u), v / np.linalg.norm(v), atol=1e-9)
    # the BVH's own rest (all zero) makes the A-pose rig stand in a T-pose
    rest = load_bvh(write_bvh(tmp_path / "r.bvh", Pose.rest(), tpose), rig=apose)
    _, p = forward_kinematics(apose.joints, rest)
    arm = p[I["LeftHand"]] - p[I["LeftArm"]]
    assert abs(arm[1]) < 1e-9 and arm[0] > 0


def test_file_facing_minus_z_is_converted(rig, tmp_path):
    half_turn = Rotation.from_euler("Y", 180, degrees=True).as_matrix()
    turned = synthetic_rig(rotate=half_turn)
    pose = random_pose(5)
    rot = Rotation.from_rotvec(pose.rotations).as_matrix()
    turned_pose = Pose(Rotation.from_matrix(half_turn @ rot @ half_turn.T).as_rotvec(), np.zeros(3))
    loaded = load_bvh(write_bvh(tmp_path / "z.bvh", turned_pose, turned), rig=rig)
    assert np.abs(pose_rig(rig, pose).vertices - pose_rig(rig, loaded).vertices).max() < 1e-9


def test_user_name_map_extends_builtin(rig, tmp_path):
    text = write_bvh(tmp_path / "a.bvh", random_pose(2), rig).read_text()
    renamed = tmp_path / "renamed.bvh"
    renamed.write_text(text.replace("JOINT LeftHand", "JOINT L_Wrist"), encoding="utf-8")
    with pytest.raises(InputError, match="LeftHand"):
        load_bvh(renamed, rig=rig)
    user_map = tmp_path / "map.yaml"
    user_map.write_text("segments:\n  LeftHand: [L_Wrist]\n", encoding="utf-8")
    loaded = load_bvh(renamed, rig=rig, name_map=user_map)
    assert np.abs(pose_rig(rig, random_pose(2)).vertices - pose_rig(rig, loaded).vertices).max() < 1e-9


def test_missing_joints_named(rig, tmp_path):
    text = write_bvh(tmp_path / "a.bvh", random_pose(1), rig).read_text()
    bad = tmp_path / "nofoot.bvh"
    text = text.replace("JOINT LeftFoot", "JOINT Stump").replace("JOINT RightHand", "JOINT Paw")
    bad.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_bvh(bad, rig=rig)
    message = str(err.value)
    assert "nofoot.bvh" in message and "LeftFoot" in message and "RightHand" in message


def test_non_numeric_motion_names_line(rig, tmp_path):
    path = write_bvh(tmp_path / "a.bvh", [random_pose(1), random_pose(2)], rig)
    lines = path.read_text().splitlines()
    values = lines[-1].split()
    values[7] = "abc"
    lines[-1] = " ".join(values)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(InputError, match=rf"a\.bvh:{len(lines)}: .*'abc'"):
        load_bvh(path, rig=rig)


@pytest.mark.parametrize(
    ("edit", "pattern"),
    [
        (lambda t: t.replace("HIERARCHY", "HIERARCHIE"), "expected HIERARCHY"),
        (lambda t: t.replace("MOTION", "MOTON"), "no MOTION section"),
        (lambda t: t.replace("Frames: 1", "Frames: 3"), "declares 3 frames"),
        (lambda t: t.replace("CHANNELS 3", "CHANNELS 3 Wrotation", 1), "unknown channel|unexpected"),
        (lambda t: t.rstrip("\n").rsplit(" ", 1)[0] + "\n", "expected 66 numbers.*got 65"),
    ],
)
def test_malformed_files(rig, tmp_path, edit, pattern):
    path = write_bvh(tmp_path / "a.bvh", random_pose(1), rig)
    path.write_text(edit(path.read_text()), encoding="utf-8")
    with pytest.raises(InputError, match=pattern):
        load_bvh(path, rig=rig)


def test_frame_out_of_range(rig, tmp_path):
    path = write_bvh(tmp_path / "a.bvh", [random_pose(1)] * 3, rig)
    with pytest.raises(InputError, match="3 frames"):
        load_bvh(path, rig=rig, frame=3)
    assert load_bvh(path, rig=rig, frame=-1).name == "a.bvh#2"


def test_units_detected_from_size(rig, tmp_path):
    path = write_bvh(tmp_path / "cm.bvh", [Pose.rest(), Pose(np.zeros((21, 3)), [0.3, 0.0, -0.2])], rig)
    assert detect_unit(read_bvh(path)) == "cm"
    assert np.allclose(load_bvh(path, rig=rig, frame=1, root_motion=True).translation, [0.3, 0.0, -0.2])
    # the same skeleton in metres
    text = path.read_text().splitlines()
    out, in_motion = [], False
    for line in text:
        if line.startswith("MOTION"):
            in_motion = True
        parts = line.split()
        if parts and parts[0] == "OFFSET":
            line = line.split("OFFSET")[0] + "OFFSET " + " ".join(str(float(v) / 100) for v in parts[1:])
        elif in_motion and parts and not line.startswith(("MOTION", "Frame")):
            vals = [float(v) for v in parts]
            vals[:3] = [v / 100 for v in vals[:3]]
            line = " ".join(map(str, vals))
        out.append(line)
    metres = tmp_path / "m.bvh"
    metres.write_text("\n".join(out) + "\n", encoding="utf-8")
    assert detect_unit(read_bvh(metres)) == "m"
    assert np.allclose(load_bvh(metres, rig=rig, frame=1, root_motion=True).translation, [0.3, 0.0, -0.2])
