"""The flat-patch baseline, and both refiners on the library's bodies."""

from __future__ import annotations

import numpy as np
import pytest

from seatkit.body import list_poses
from seatkit.errors import RecipeError, UnsupportedPoseError
from seatkit.refine import (
    CatmullClarkFitRefiner,
    OptimizeRefiner,
    fit_report,
)
from seatkit.skeleton import SEGMENT_INDEX
from seatkit.template.flat_patch import FlatPatchTemplate
from seatkit.template.quad_grid import grid_ring


def test_flat_patch_shape(seated):
    body, pressure = seated["upright-sitting"]
    mesh = FlatPatchTemplate().fit([body], [pressure])
    rows, cols = 11, 7
    assert mesh.faces.shape == (rows * cols, 4)
    assert mesh.vertices.shape == ((rows + 1) * (cols + 1), 3)
    ring = grid_ring(rows, cols, 0)
    assert np.array_equal(mesh.ground, ring) and np.array_equal(mesh.fixed, ring)
    assert np.all(mesh.vertices[ring, 1] == 0.0)
    # flat part: one height, under every supported vertex (or at 2 cm)
    top = mesh.vertices[~ring, 1]
    assert np.ptp(top) == 0.0
    dominant = np.argmax(body.weights, axis=1)
    segs = mesh.meta["supported_segments"]
    supported = (pressure.importance > 0.02) & np.isin(dominant, segs)
    assert top[0] == pytest.approx(max(body.vertices[supported, 1].min(), 0.02))
    # it covers the supported footprint; the ground ring lies outside it
    pts = body.vertices[supported]
    inner = mesh.vertices[~ring]
    assert inner[:, 0].min() <= pts[:, 0].min() + 1e-12 and inner[:, 0].max() >= pts[:, 0].max() - 1e-12
    assert inner[:, 2].min() <= pts[:, 2].min() + 1e-12 and inner[:, 2].max() >= pts[:, 2].max() - 1e-12
    # normals point up (at the body)
    v = mesh.vertices
    f = mesh.faces[~mesh.ground[mesh.faces].any(axis=1)]
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 3]] - v[f[:, 0]])
    assert np.all(normals[:, 1] > 0)
    assert SEGMENT_INDEX["Hips"] in segs and SEGMENT_INDEX["Head"] not in segs


def test_flat_patch_parameters(seated):
    body, pressure = seated["upright-sitting"]
    mesh = FlatPatchTemplate().fit([body], [pressure], params={"rows": 9, "cols": 5, "height": 0.3})
    assert mesh.faces.shape == (45, 4)
    assert np.all(mesh.vertices[~mesh.ground, 1] == 0.3)
    with pytest.raises(RecipeError, match="unknown segment"):
        FlatPatchTemplate().fit([body], [pressure], params={"segments": ["Tail"]})
    with pytest.raises(RecipeError, match=r"^template_params.colums: template 'flat-patch' has no option 'colums'; .*did you mean 'cols'\?"):
        FlatPatchTemplate().fit([body], [pressure], params={"colums": 5})


def test_flat_patch_fit_upright_sitting(seated):
    body, pressure = seated["upright-sitting"]
    mesh = FlatPatchTemplate().fit([body], [pressure])
    out = CatmullClarkFitRefiner().refine(mesh, [body], [pressure])
    before = fit_report(mesh, [body], [pressure])
    after = fit_report(out, [body], [pressure])
    # the fit brings the patch from the floor up to the seat and back
    assert after["mean_distance"] < 0.25 * before["mean_distance"]
    assert np.array_equal(out.vertices[mesh.ground], mesh.vertices[mesh.ground])


def _chair_or_skip(body, pressure):
    from seatkit.plugins import get_plugin_manager

    registry = get_plugin_manager(autoload=False).registry
    if "chair" not in registry.names("template"):
        pytest.skip("chair template not registered")
    try:
        return registry.get("template", "chair").fit([body], [pressure])
    except UnsupportedPoseError as exc:
        pytest.skip(f"chair template does not fit this pose: {exc}")


@pytest.mark.parametrize("pose", [info.name for info in list_poses() if info.supported])
def test_chair_after_both_refiners_beats_flat_patch(seated, pose):
    body, pressure = seated[pose]
    chair = _chair_or_skip(body, pressure)
    optimised = OptimizeRefiner().refine(chair, [body], [pressure])
    report = optimised.meta["optimize"]
    assert report["after"]["planarity_mean"] < report["before"]["planarity_mean"]
    assert report["after"]["regularity_deg"] < report["before"]["regularity_deg"]
    assert report["after"]["min_angle_deg"] >= report["before"]["min_angle_deg"]
    fitted = CatmullClarkFitRefiner().refine(optimised, [body], [pressure])
    ours = fit_report(fitted, [body], [pressure])
    segments = fitted.meta["catmull-clark-fit"]["supported_segments"][0]
    flat = FlatPatchTemplate().fit([body], [pressure], params={"segments": segments})
    # the baseline is measured, not delivered: no 5 mm refusal (as seatkit.pipeline.fit_baseline)
    baseline = fit_report(CatmullClarkFitRefiner().refine(flat, [body], [pressure], params={"surface_limit": 0.0}), [body], [pressure])
    # the paper's Table 1 distance (supported body vertices to the surface)
    assert ours["avg_distance"] < baseline["avg_distance"]
    # no body vertex more than 5 mm inside the surface, read both ways: the
    # surface below the skin, and body vertices inside the furniture
    assert ours["max_penetration"] <= 0.005
    assert ours["max_body_depth"] <= 0.005
