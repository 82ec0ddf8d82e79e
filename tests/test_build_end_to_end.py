"""A whole build, as the pipeline runs it: files, determinism, the folder contract."""

import filecmp
import json

import numpy as np

from seatkit.pipeline import build

RECIPE = {"template": "chair", "exporters": ["usd", "obj", "surface", "design"], "evaluate": {"enabled": False}, "seed": 5}


def test_same_inputs_and_seed_give_byte_identical_files(tmp_path):
    first, second = tmp_path / "a", tmp_path / "b"
    ra = build(dict(RECIPE, output=str(first)))
    build(dict(RECIPE, output=str(second)))
    for name in ("cage.usda", "cage.obj", "surface.stl", "surface.glb", "surface.obj"):
        assert filecmp.cmp(first / name, second / name, shallow=False), name
    # design.npz records the recipe, whose output folder differs here: the rest is identical
    da, db = np.load(first / "design.npz"), np.load(second / "design.npz")
    assert da.files == db.files
    for key in da.files:
        if key == "header":
            ha, hb = (json.loads(bytes(d[key])) for d in (da, db))
            ha["recipe"].pop("output"), hb["recipe"].pop("output")
            assert ha == hb
        else:
            np.testing.assert_array_equal(da[key], db[key])
    # the folder is complete and says so; every listed file exists
    marker = json.loads((first / ".seatkit-run").read_text())
    assert marker["complete"] is True
    assert all((first / n).is_file() for n in ("cage.usda", "cage.obj", "surface.stl", "report.json", "design.npz"))
    # the ground ring lies on the floor; the limit surface stays (almost) above it:
    # the fit keeps its targets above y = 0 and does not push it out of the soles
    # downwards; Catmull-Clark smoothing near the ground ring dips it by a few mm
    mesh = ra.control_mesh
    assert abs(mesh.vertices[mesh.ground, 1]).max() < 1e-9
    assert ra.surface.vertices[:, 1].min() > -0.01
    report = json.loads((first / "report.json").read_text())
    assert set(report["timings_s"]) >= {"bodies", "pressure", "template", "refine:optimize", "refine:catmull-clark-fit", "export"}
    # the design search names the winning candidate's origin and judged it within the 5 mm limit
    search = report["search"]
    won = search["candidates"][search["winner"]["candidate"] - 1]
    assert won["accepted"] and won["origin"] == search["winner"]["origin"] in {"start", "walls-inside", "pushed-out", "walls-against", "last-resort"}
    assert won["depth_m"] <= 0.005 and all(c["reason"] for c in search["candidates"] if not c["accepted"])
    assert "search" not in report["control_mesh"]["meta"]
