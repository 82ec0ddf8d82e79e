"""Virtual sitting trials (seatkit.trial, ``seatkit trial``): the placement and the figures on a fixed design."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from seatkit.cli import app


@pytest.fixture(scope="module")
def design_dir(p50_upright_design):
    return p50_upright_design


@pytest.fixture(scope="module")
def registry():
    from seatkit.plugins import get_plugin_manager

    return get_plugin_manager().registry


def test_trial_of_the_design_s_own_sitter_reproduces_its_build(design_dir, registry):
    from seatkit.trial import load_trial_design, run_trial

    report = json.loads((design_dir / "report.json").read_text())
    built = report["metrics"]["ours"][0]
    design = load_trial_design(design_dir)
    trial = run_trial(design, registry, "p50-male", {}, "upright-sitting")
    theta = trial.placement.theta
    # the placement lands where the build placed the person: translation within 2 mm, joints within 1 degree
    assert np.abs(theta[:3]).max() <= 0.002, theta
    assert np.degrees(np.abs(theta[3:])).max() <= 1.0, np.degrees(theta[3:])
    m = trial.metrics
    assert m["supported"] and built["supported"]
    # the figures are the build's, within stated tolerances
    assert m["avg_distance_m"] == pytest.approx(built["avg_distance_m"], abs=0.001)
    assert m["max_penetration_m"] <= 0.005 and m["max_body_depth_m"] <= 0.005
    assert m["max_moment_nm"] == pytest.approx(built["max_moment_nm"], rel=0.05)
    assert m["avg_pressure_pa"] == pytest.approx(built["avg_pressure_pa"], rel=0.10)
    assert m["contact_vertices"] == pytest.approx(built["contact_vertices"], rel=0.10)
    fit = trial.fit
    assert fit["seat_height_m"] == pytest.approx(report["metrics"]["person_fit"][0]["seat_height_m"], abs=0.005)
    # the forces hold the body: the reactions sum to its weight
    assert trial.field.force[:, 1].sum() == pytest.approx(trial.body.mass * 9.81, rel=1e-3)


def test_a_shorter_person_is_lifted_onto_the_seat_and_a_larger_one_is_held_clear_of_it(design_dir, registry):
    from seatkit.trial import load_trial_design, run_trial

    design = load_trial_design(design_dir)
    small = run_trial(design, registry, "p5-female", {}, "upright-sitting")
    large = run_trial(design, registry, "p95-male", {}, "upright-sitting")
    # posed with the feet on the floor, a p5 woman's pelvis is below this seat: she is lifted onto it
    assert small.placement.theta[1] > 0.03
    for t in (small, large):
        assert t.metrics["supported"]
        assert t.metrics["max_body_depth_m"] <= 0.005  # no part of the body inside the furniture
        assert t.placement.cost < t.placement.base_cost
    # her feet no longer reach the floor: the seat is higher than her popliteal height with shoes
    assert small.fit["seat_height_difference_m"] > 0.02
    assert small.body.vertices[:, 1].min() > 0.0


def test_trial_command_writes_its_figures_and_picture(design_dir, tmp_path):
    from PIL import Image

    out = tmp_path / "t"
    res = CliRunner().invoke(app, ["trial", str(design_dir), "--body", "p50-female", "--out", str(out)])
    assert res.exit_code == 0, res.output
    data = json.loads((out / "trial.json").read_text())
    assert data["person"]["body"].startswith("p50-female")
    assert set(data["metrics"]) >= {"avg_distance_m", "max_penetration_m", "max_body_depth_m", "supported"}
    assert data["person_fit"]["popliteal_height_m"] > 0.3
    with Image.open(out / "trial.png") as im:
        pixels = np.asarray(im.convert("RGB")).reshape(-1, 3)
    assert len(pixels) > 600 * 300 and len(np.unique(pixels, axis=0)) > 100  # a drawn picture, not a blank


@pytest.mark.parametrize(
    "args, expected",
    [
        (["trial", "/no/such/folder"], "no such folder"),
        (["trial", "{design}", "--body", "nobody"], "unknown body model"),
        (["trial", "{design}", "--pose", "no-such-pose"], "unknown pose"),
        (["trial", "{design}", "--seat", "2"], "--seat: expected a sitter of the design from 1 to 1"),
    ],
)
def test_trial_bad_input_gets_one_line(design_dir, tmp_path, args, expected):
    args = [a.format(design=design_dir) for a in args]
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "x")])
    assert res.exit_code != 0
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and expected in lines[0], res.output
    assert not (tmp_path / "x").exists()


def test_the_posed_points_the_placement_measures_are_those_of_a_fresh_pose(registry):
    """Skinned points kept between evaluations (a Jacobian moves one unknown at a time) never stand for another pose or subset."""
    import gc

    from seatkit.body import load_pose
    from seatkit.trial import _Poser

    model = registry.get("body_model", "p50-male")
    rig = model.make_body(params={})
    pose = load_pose("upright-sitting", rig=rig, dirs=registry.pose_dirs)
    poser = _Poser(model, rig, pose)
    rng = np.random.default_rng(0)
    n = len(rig.vertices)
    for _ in range(12):
        # a new subset each time (the old one freed): its id may be an old one's
        subset = poser.subset(rng.choice(n, size=int(rng.integers(50, 400)), replace=False))
        theta = np.r_[rng.uniform(-0.05, 0.05, 3), rng.uniform(-0.2, 0.2, 5)] * rng.integers(0, 2, 8)
        got = poser.points(theta, subset)
        fresh = _Poser(model, rig, pose).points(theta, poser.subset(subset[0]))
        np.testing.assert_allclose(got, fresh, atol=1e-12)
        # the translation and the heading moved alone (as a finite difference does) move the points rigidly
        moved = theta.copy()
        moved[:4] += [0.01, -0.02, 0.003, 0.05]
        np.testing.assert_allclose(poser.points(moved, subset), _Poser(model, rig, pose).points(moved, poser.subset(subset[0])), atol=1e-12)
        del subset
        gc.collect()
    # the whole body at theta is the body model's own pose of it
    theta = np.array([0.01, 0.02, -0.01, 0.1, 0.15, -0.1, 0.05, 0.08])
    whole = poser.points(theta, poser.subset(np.arange(n)))
    np.testing.assert_allclose(whole, poser.body(theta).vertices[:n], atol=1e-6)


@pytest.fixture(scope="module")
def small_design(tmp_path_factory):
    """A p5-female upright chair: a seat lower than most people's own."""
    from seatkit import build

    out = tmp_path_factory.mktemp("design") / "p5f"
    build({
        "template": "chair", "bodies": [{"model": "p5-female", "pose": "upright-sitting"}], "output": str(out),
        "exporters": ["design", "report-json"], "evaluate": {"baseline": None},
    }, processes=False)
    return out


def test_a_person_whose_own_seat_is_higher_comes_down_onto_the_seat_with_the_feet_on_the_floor(small_design, registry):
    from seatkit.body import load_pose
    from seatkit.constants import GRAVITY
    from seatkit.skeleton import SEGMENT_INDEX as S
    from seatkit.trial import _Poser, load_trial_design, run_trial

    design = load_trial_design(small_design)
    model = registry.get("body_model", "p50-male")
    rig = model.make_body(params={})
    posed = _Poser(model, rig, load_pose("upright-sitting", rig=rig, dirs=registry.pose_dirs)).body0

    def pelvis_bottom(body):
        return body.vertices[np.argmax(body.weights, axis=1) == S["Hips"], 1].min()

    # posed as a build poses him (feet on the floor), his pelvis is 8 to 12 cm above this seat's sitter's
    assert 0.08 <= pelvis_bottom(posed) - pelvis_bottom(design.bodies[0]) <= 0.12
    person = run_trial(design, registry, "p50-male", {}, "upright-sitting")
    m = person.metrics
    assert m["supported"]
    assert m["max_penetration_m"] <= 0.005 and m["max_body_depth_m"] <= 0.005  # nothing cut
    part = np.argmax(person.body.weights, axis=1)
    # he came down onto the seat (more than 5 cm; a wider pelvis rests higher in a seat shaped for a narrower one)
    # and the seat carries him on his pelvis and thighs
    assert pelvis_bottom(person.body) < pelvis_bottom(posed) - 0.05
    seated = np.isin(part, [S["Hips"], S["RightUpLeg"], S["LeftUpLeg"]])
    assert person.field.force[seated, 1].sum() > 0.5 * person.body.mass * GRAVITY
    # his feet stay on the floor (the lower legs forward), they neither hang nor go through it
    for side in ("Right", "Left"):
        foot = person.body.vertices[part == S[f"{side}Foot"], 1]
        assert -0.002 <= foot.min() <= design.support_distance
    assert person.fit["seat_height_difference_m"] < -0.05  # a seat lower than his popliteal height with shoes
