"""Forward kinematics and linear blend skinning."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from seatkit.body import load_rig, pose_rig
from seatkit.body.skinning import forward_kinematics
from seatkit.model import Pose
from seatkit.skeleton import N_SEGMENTS, PARENTS, SEGMENT_INDEX


@pytest.fixture(scope="module")
def rig():
    return load_rig("default-male")


def descendants(seg):
    out = {seg}
    for s in range(N_SEGMENTS):
        p = s
        while p >= 0:
            if p == seg:
                out.add(s)
                break
            p = PARENTS[p]
    return out


def random_pose(seed):
    rng = np.random.default_rng(seed)
    return Pose(rng.normal(scale=0.5, size=(N_SEGMENTS, 3)), rng.normal(scale=0.2, size=3), "random")


def test_rest_pose_is_identity(rig):
    body = pose_rig(rig, Pose.rest(), ground=False)
    np.testing.assert_allclose(body.vertices, rig.vertices, atol=1e-12)
    np.testing.assert_allclose(body.joints, rig.joints, atol=1e-12)
    np.testing.assert_allclose(body.segment_com, rig.joints + rig.com_ratio[:, None] * (rig.tips - rig.joints))
    assert body.mass == pytest.approx(75.0)


def test_rotation_of_right_leg_moves_only_descendants(rig):
    rot = np.zeros((N_SEGMENTS, 3))
    knee = SEGMENT_INDEX["RightLeg"]
    rot[knee] = [np.radians(70), 0, 0]
    body = pose_rig(rig, Pose(rot, np.zeros(3)), ground=False)
    moved = np.flatnonzero(np.linalg.norm(body.tips - rig.tips, axis=1) > 1e-12)
    assert set(moved) == descendants(knee) == {knee, SEGMENT_INDEX["RightFoot"]}
    # the knee joint itself does not move, and vertices fully bound elsewhere stay put
    np.testing.assert_allclose(body.joints[knee], rig.joints[knee], atol=1e-12)
    w_leg_chain = rig.weights[:, [knee, SEGMENT_INDEX["RightFoot"]]].sum(axis=1)
    still = w_leg_chain == 0
    np.testing.assert_allclose(body.vertices[still], rig.vertices[still], atol=1e-12)
    assert np.linalg.norm(body.vertices[w_leg_chain == 1] - rig.vertices[w_leg_chain == 1], axis=1).max() > 0.2


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bone_lengths_and_joint_chain_preserved(rig, seed):
    body = pose_rig(rig, random_pose(seed), ground=True)
    np.testing.assert_allclose(
        np.linalg.norm(body.tips - body.joints, axis=1), np.linalg.norm(rig.tips - rig.joints, axis=1), atol=1e-12
    )
    child = np.arange(1, N_SEGMENTS)
    np.testing.assert_allclose(
        np.linalg.norm(body.joints[child] - body.joints[PARENTS[child]], axis=1),
        np.linalg.norm(rig.joints[child] - rig.joints[PARENTS[child]], axis=1),
        atol=1e-12,
    )
    assert body.vertices[:, 1].min() == pytest.approx(0.0, abs=1e-12)
    assert np.isfinite(body.vertices).all()


def test_fk_matches_the_documented_convention(rig):
    pose = random_pose(7)
    glob, joints = forward_kinematics(rig.joints, pose)
    R = Rotation.from_rotvec(pose.rotations).as_matrix()
    np.testing.assert_allclose(glob[0], R[0])
    np.testing.assert_allclose(joints[0], rig.joints[0] + pose.translation)
    for s in range(1, N_SEGMENTS):
        p = PARENTS[s]
        np.testing.assert_allclose(glob[s], glob[p] @ R[s], atol=1e-12)
        np.testing.assert_allclose(joints[s], joints[p] + glob[p] @ (rig.joints[s] - rig.joints[p]), atol=1e-12)


def test_vertices_bound_to_one_segment_move_rigidly(rig):
    pose = random_pose(3)
    body = pose_rig(rig, pose, ground=False)
    glob, joints = forward_kinematics(rig.joints, pose)
    for s in (SEGMENT_INDEX["Head"], SEGMENT_INDEX["LeftUpLeg"]):
        rigid = rig.weights[:, s] == 1.0
        assert rigid.sum() > 50
        expected = (rig.vertices[rigid] - rig.joints[s]) @ glob[s].T + joints[s]
        np.testing.assert_allclose(body.vertices[rigid], expected, atol=1e-12)


def test_whole_body_rotation_is_rigid_and_translation_adds(rig):
    rot = np.zeros((N_SEGMENTS, 3))
    rot[0] = [0.3, -0.2, 0.5]
    t = np.array([0.1, 0.2, -0.3])
    body = pose_rig(rig, Pose(rot, t), ground=False)
    G = Rotation.from_rotvec(rot[0]).as_matrix()
    expected = (rig.vertices - rig.joints[0]) @ G.T + rig.joints[0] + t
    np.testing.assert_allclose(body.vertices, expected, atol=1e-12)


def test_segment_com_follows_pose(rig):
    body = pose_rig(rig, random_pose(5))
    np.testing.assert_allclose(body.segment_com, body.joints + rig.com_ratio[:, None] * (body.tips - body.joints))
