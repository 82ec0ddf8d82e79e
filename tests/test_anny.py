"""The parametric ``anny`` body model plugin (plugins/seatkit_anny).

Tests marked ``anny`` need the extra (``pip install 'seatkit[anny]'``) and
skip without it. anny's first use builds a cache of about 800 MB in about
two minutes (under ``$SEATKIT_CACHE_DIR/anny``).
"""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from seatkit.errors import MissingExtraError, RecipeError
from seatkit.interfaces import BodyModel
from seatkit.skeleton import N_SEGMENTS, SEGMENT_INDEX as I

seatkit_anny = pytest.importorskip("seatkit_anny", reason="plugins/ is not on the path")
from seatkit_anny import model as anny_model  # noqa: E402

HAVE_ANNY = importlib.util.find_spec("anny") is not None and importlib.util.find_spec("torch") is not None
needs_anny = [pytest.mark.anny, pytest.mark.skipif(not HAVE_ANNY, reason="the anny extra is not installed")]


def test_plugin_registers_a_body_model():
    (component,) = seatkit_anny.seatkit_register_body_models()
    assert component.name == "anny" and isinstance(component, BodyModel)


def test_missing_extra_is_reported(monkeypatch):
    monkeypatch.setattr(anny_model, "_STATE", {})
    monkeypatch.setitem(sys.modules, "anny", None)  # import anny -> ImportError
    with pytest.raises(MissingExtraError) as info:
        anny_model.AnnyBodyModel().make_body(params={})
    # the torch-first step of docs/bodies.md, then the extra
    assert str(info.value) == (
        "this feature needs the optional package 'anny': install it with "
        "pip install torch==2.13.0 first, then pip install 'seatkit[anny]'"
    )
    assert "pip install torch==2.13.0" in (anny_model.Path(__file__).parents[1] / "docs" / "bodies.md").read_text()


@pytest.mark.parametrize(
    ("params", "pattern"),
    [
        ({"hight": 0.5}, "unknown parameter.*hight"),
        ({"age": 1.5}, "age must be a number from 0 to 1"),
        ({"weight": "heavy"}, "weight must be a number"),
        ({"mass": -3}, "mass must be a positive"),
        ({"stature": 175}, "stature must be a height in metres"),
        ({"sex": "other"}, "sex must be"),
    ],
)
def test_bad_parameters(params, pattern):
    with pytest.raises(RecipeError, match=pattern):
        anny_model.AnnyBodyModel().make_body(params=params)


def test_cache_folder(monkeypatch, tmp_path):
    monkeypatch.delenv("ANNY_CACHE_DIR", raising=False)
    monkeypatch.setenv("SEATKIT_CACHE_DIR", str(tmp_path / "sk"))
    assert anny_model.anny_cache_dir() == tmp_path / "sk" / "anny"
    monkeypatch.delenv("SEATKIT_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert anny_model.anny_cache_dir() == tmp_path / "xdg" / "seatkit" / "anny"
    monkeypatch.setenv("ANNY_CACHE_DIR", str(tmp_path / "mine"))
    assert anny_model.anny_cache_dir() == tmp_path / "mine"


@pytest.fixture(scope="module")
def male():
    return anny_model.AnnyBodyModel().make_body(params={"stature": 1.75, "mass": 80.0})


@pytest.mark.anny
@pytest.mark.skipif(not HAVE_ANNY, reason="the anny extra is not installed")
def test_anny_rig_invariants(male):
    import anny.paths

    assert anny.paths.get_anny_cache_path() == anny_model.anny_cache_dir()
    n = len(male.vertices)
    assert male.weights.shape == (n, N_SEGMENTS) and n > 10000
    assert (male.weights >= 0).all() and np.allclose(male.weights.sum(axis=1), 1.0)
    assert ((male.weights > 0).sum(axis=0) > 0).all()  # every segment owns vertices
    assert male.segment_mass.sum() == pytest.approx(80.0)
    assert male.faces.max() < n and np.isfinite(male.vertices).all()
    # seatkit axes, T-pose: feet on y = 0, left arm along +X, facing +Z (toes ahead of ankles)
    assert male.vertices[:, 1].min() == pytest.approx(0.0)
    arm = male.joints[I["LeftHand"]] - male.joints[I["LeftArm"]]
    assert arm[0] > 0.4 and abs(arm[1]) < 1e-6 and abs(arm[2]) < 1e-6
    assert male.tips[I["LeftFoot"]][2] > male.joints[I["LeftFoot"]][2] + 0.1
    assert male.joints[I["Head"]][1] > male.joints[I["Neck"]][1] > male.joints[I["Spine3"]][1]


@pytest.mark.anny
@pytest.mark.skipif(not HAVE_ANNY, reason="the anny extra is not installed")
def test_anny_reproduces_embedded_default_body(male):
    """The default-male phenotype through the plugin gives the shipped default-male body."""
    from seatkit.body.rig import default_body_path, load_rig_file

    default = load_rig_file(default_body_path("default-male"))  # the shipped mesh (load_rig makes the 75 kg body)
    assert male.vertices.shape == default.vertices.shape
    assert np.abs(male.vertices - default.vertices).max() < 1e-5  # float32 storage (7e-8 seen)
    assert np.abs(male.joints - default.joints).max() < 1e-5
    assert np.abs(male.weights - default.weights).max() < 1e-6  # same bone grouping
    assert np.abs(male.tips - default.tips).max() < 1e-5
    assert set(male.region_labels) == set(default.region_labels)


@pytest.mark.anny
@pytest.mark.skipif(not HAVE_ANNY, reason="the anny extra is not installed")
def test_anny_phenotype_and_posing(male):
    from seatkit.body import pose_rig
    from seatkit.body.anthropometry import segment_mass_fractions
    from seatkit.body.poses import load_pose

    female = anny_model.AnnyBodyModel().make_body(params={"gender": 1.0, "height": 0.3})
    assert female.meta["sex"] == "female"
    assert np.allclose(female.segment_mass / female.mass, segment_mass_fractions("female"))
    assert female.meta["stature_m"] < male.meta["stature_m"]
    body = anny_model.AnnyBodyModel().pose(male, load_pose("upright-sitting"))
    assert np.isfinite(body.vertices).all()
    assert body.vertices[:, 1].min() == pytest.approx(0.0, abs=1e-9)
    # seated: thighs level, knees ahead of the hips, hips about knee height
    thigh = body.joints[I["LeftLeg"]] - body.joints[I["LeftUpLeg"]]
    assert thigh[2] > 0.3 and abs(thigh[1]) < 0.1
    assert body.mass == pytest.approx(80.0)
    assert np.allclose(body.vertices, pose_rig(male, load_pose("upright-sitting")).vertices)
