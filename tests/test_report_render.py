"""The report exporters: the z-buffer rasteriser, the PNG renders and report.html."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest
from PIL import Image

from seatkit.picture import raster as rs
from seatkit.export import report
from test_report_support import evaluated_result, plain_result

# ----------------------------------------------------------------------------- rasteriser


def _brute_force(frame, vertices, faces):
    """Nearest depth and triangle per pixel centre, one triangle at a time."""
    xy, z = frame.project(vertices)
    h, w = frame.height, frame.width
    cy, cx = np.mgrid[0:h, 0:w] + 0.5
    depth = np.full((h, w), -np.inf)
    face = np.full((h, w), -1)
    for t, (a, b, c) in enumerate(faces):
        (ax, ay), (bx, by), (qx, qy) = xy[a], xy[b], xy[c]
        area = (bx - ax) * (qy - ay) - (qx - ax) * (by - ay)
        l1 = ((cx - ax) * (qy - ay) - (qx - ax) * (cy - ay)) / area
        l2 = ((bx - ax) * (cy - ay) - (cx - ax) * (by - ay)) / area
        l0 = 1 - l1 - l2
        inside = (l0 >= 1e-6) & (l1 >= 1e-6) & (l2 >= 1e-6)
        zz = l0 * z[a] + l1 * z[b] + l2 * z[c]
        better = inside & (zz > depth)
        depth[better], face[better] = zz[better], t
    return depth, face


def test_zbuffer_matches_brute_force_on_interpenetrating_triangles():
    rng = np.random.default_rng(3)
    vertices = rng.uniform(-1, 1, size=(60, 3))
    faces = np.arange(60).reshape(20, 3)
    frame = rs.fit_frame([vertices], rs.view_rotation(30, 20), 64, 48)
    ra = rs.rasterize(frame, vertices, faces)
    depth, face = _brute_force(frame, vertices, faces)
    # pixels strictly inside a triangle (the brute force ignores edge ties) agree exactly
    sure = face >= 0
    assert sure.sum() > 500
    assert np.array_equal(ra.face[sure], face[sure])
    assert np.allclose(ra.depth[sure], depth[sure], atol=1e-4)
    # and the rasteriser covers no pixel that no triangle covers (up to edge ties)
    assert ra.mask.sum() >= sure.sum()
    assert ra.mask.sum() - sure.sum() < 0.05 * sure.sum()


def test_shared_edge_leaves_no_gap_and_no_double_cover():
    # a 20 x 10 pixel rectangle made of two triangles, exactly on pixel borders
    frame = rs.Frame(np.eye(3), 1.0, 0.0, 32.0, 32, 32)
    vertices = np.array([[4, 12, 0], [24, 12, 0], [24, 22, 0], [4, 22, 0]], float)
    vertices[:, 1] = 32 - vertices[:, 1]  # camera y up, pixel rows down
    quads = np.array([[0, 1, 2, 3]])
    ra = rs.rasterize(frame, vertices, report._tri(quads))
    assert ra.mask.sum() == 20 * 10
    assert np.allclose(ra.bary.sum(axis=1), 1.0, atol=1e-5)


def test_back_faces_are_culled_and_visible_side_is_kept():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    frame = rs.fit_frame([vertices], rs.view_rotation(0, 0), 40, 40)
    ccw = rs.rasterize(frame, vertices, np.array([[0, 1, 2]]), cull_back=True)
    cw = rs.rasterize(frame, vertices, np.array([[0, 2, 1]]), cull_back=True)
    assert ccw.mask.sum() > 300 and cw.mask.sum() == 0


def test_translucent_layer_blends_only_in_front_of_opaque():
    frame = rs.Frame(np.eye(3), 1.0, 0.0, 8.0, 8, 8)
    quad = np.array([[0, 1, 2, 3]])
    back = np.array([[0, 0, 0], [8, 0, 0], [8, 8, 0], [0, 8, 0]], float)
    half = np.array([[0, 0, 1], [4, 0, 1], [4, 8, 1], [0, 8, 1]], float)  # nearer, left half
    behind = half + [4, 0, -2]  # farther, right half
    tri = report._tri(quad)
    r_back, r_near, r_far = (rs.rasterize(frame, v, tri) for v in (back, half, behind))
    red = np.array([1.0, 0, 0])
    img = rs.composite(
        [1, 1, 1],
        [
            (r_back, np.tile([0.0, 0, 1], (r_back.covered.size, 1)), 1.0),
            (r_near, np.tile(red, (r_near.covered.size, 1)), 0.5),
            (r_far, np.tile(red, (r_far.covered.size, 1)), 0.5),
        ],
    )
    assert np.allclose(img[4, 1], [0.5, 0, 0.5])  # blended over the blue quad
    assert np.allclose(img[4, 6], [0, 0, 1])  # hidden behind the blue quad


# ----------------------------------------------------------------------------- PNGs


@pytest.fixture(scope="module")
def pngs(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    return out, report.ReportPngExporter().export(evaluated_result(), out)


def _rgb(path):
    return np.asarray(Image.open(path).convert("RGB")).astype(np.int64)


def _near(img, color, tol=12):
    return (np.abs(img - np.asarray(color)).max(axis=-1) <= tol).sum()


def test_png_files_and_roles(pngs):
    out, files = pngs
    assert set(files) == set(report.PNG_FILES)
    for role, path in files.items():
        assert path.parent == out and path.name == report.PNG_FILES[role]
        img = _rgb(path)
        assert img.ndim == 3 and img.shape[0] >= report.PANEL_HEIGHT and img.shape[1] >= 2 * report.PANEL_WIDTH
        # the renders are not blank: many colours, and the body's shading
        assert len(np.unique(img.reshape(-1, 3) @ [65536, 256, 1])) > 300


def test_pressure_png_shows_the_dark_end_of_the_scale_on_the_body(pngs):
    _, files = pngs
    img = _rgb(files["report_pressure_png"])
    pos, stops = report._colorscale_stops()
    dark = np.round(255 * stops[-2]).astype(int)  # the scale's second-darkest stop
    panels = img[:, : 3 * report.PANEL_WIDTH]  # exclude the colour bar
    # shading darkens the colours, so look for hue close to the dark stops in the back view
    back = panels[:, report.PANEL_WIDTH :]
    purple = (back[..., 2] > back[..., 1] + 30) & (back[..., 0] > back[..., 1] + 15)
    assert purple.sum() > 100, "no high-pressure colour on the back view"
    assert _near(img[:, 3 * report.PANEL_WIDTH :], dark, tol=8) > 10  # the colour bar holds the same scale


def test_rendering_writes_every_picture_in_role_order_and_surfaces_a_drawing_error(tmp_path, monkeypatch):
    result = evaluated_result()
    for name in ("one", "two"):
        (tmp_path / name).mkdir()
    one = report.render_pngs(result, tmp_path / "one")
    assert list(one) == list(report.PNG_FILES)  # roles in the same order
    for role, path in one.items():
        assert path == tmp_path / "one" / report.PNG_FILES[role] and path.stat().st_size > 0, role

    def broken(scene, path, save):
        raise report.InputError("cannot draw the pressure")

    monkeypatch.setattr(report, "_pressure_png", broken)
    with pytest.raises(report.InputError, match="cannot draw the pressure"):
        report.render_pngs(result, tmp_path / "two")


def test_the_pictures_drawn_in_parts_are_the_whole_pictures(tmp_path):
    """A build with idle helper processes draws the report's parts apart: together they are export()'s files, byte for byte, in its order."""
    result = evaluated_result()
    exporter = report.ReportPngExporter()
    (tmp_path / "whole").mkdir()
    whole = exporter.export(result, tmp_path / "whole")
    written = []
    for part in range(exporter.parts):
        (tmp_path / f"part{part}").mkdir()
        written.append(exporter.export_part(result, tmp_path / f"part{part}", part))
    joined = exporter.join_parts(written)
    assert list(joined) == list(whole) == list(report.PNG_FILES)
    for role, path in joined.items():
        assert path.read_bytes() == whole[role].read_bytes(), role


def test_the_pictures_drawn_early_are_those_of_the_result_and_only_of_its_bodies(tmp_path):
    """A build with helpers draws pressure.png from the bodies and their importance before the design exists: the same bytes; a payload drawn from other bodies is not used."""
    import dataclasses

    from seatkit.model import BuildResult

    result = evaluated_result()
    exporter = report.ReportPngExporter()
    (tmp_path / "whole").mkdir()
    whole = exporter.export(result, tmp_path / "whole")
    early = exporter.export_early(BuildResult(result.recipe, result.bodies, result.pressures))
    assert set(early["png"]) == set(report.EARLY_PNGS)
    assert early["png"]["report_pressure_png"] == whole["report_pressure_png"].read_bytes()
    written = []
    for part in range(exporter.parts):
        (tmp_path / f"part{part}").mkdir()
        written.append(exporter.export_part(result, tmp_path / f"part{part}", part, early=early))
    for role, path in exporter.join_parts(written).items():
        assert path.read_bytes() == whole[role].read_bytes(), role
    # bodies moved after their importance was drawn (a seat height set, sitters): drawn again
    body = result.bodies[0]
    moved = dataclasses.replace(body, vertices=body.vertices * [1.3, 1.0, 1.0])  # a picture of its own (a move alone is framed away)
    other = dataclasses.replace(result, bodies=[moved])
    (tmp_path / "moved").mkdir()
    again = exporter.export(other, tmp_path / "moved", early=early)
    (tmp_path / "fresh").mkdir()
    fresh = exporter.export(other, tmp_path / "fresh")
    assert again["report_pressure_png"].read_bytes() == fresh["report_pressure_png"].read_bytes() != early["png"]["report_pressure_png"]
    stale = dataclasses.replace(result, pressures=[dataclasses.replace(p, pressure=p.pressure * 2) for p in result.pressures])
    (tmp_path / "stale").mkdir()
    redrawn = exporter.export_part(stale, tmp_path / "stale", report.PNG_PARTS.index(("report_pressure_png", "report_interface_png")), early=early)
    assert redrawn["report_pressure_png"].read_bytes() != early["png"]["report_pressure_png"]


def test_the_bodies_rasters_kept_from_other_pictures_draw_the_same_pictures(tmp_path):
    """The bodies' views kept in the process (pressure.png's, drawn ahead) give every picture's bytes as drawing them anew does; other bodies get their own."""
    import dataclasses

    result = evaluated_result()
    anew = {}
    for role in report.PNG_FILES:
        report._BODY_RASTERS.clear()
        (tmp_path / role).mkdir()
        anew.update(report.render_pngs(result, tmp_path / role, roles=(role,)))
    report._BODY_RASTERS.clear()
    report.draw_early_pngs(result)  # the bodies' front, back and from-below views kept
    assert len(report._BODY_RASTERS) == 3
    (tmp_path / "kept").mkdir()
    kept = report.render_pngs(result, tmp_path / "kept")
    assert list(kept) == list(anew)
    for role, path in kept.items():
        assert path.read_bytes() == anew[role].read_bytes(), role
    body = result.bodies[0]
    other = dataclasses.replace(result, bodies=[dataclasses.replace(body, vertices=body.vertices * [1.3, 1.0, 1.0])])
    (tmp_path / "other").mkdir()
    drawn = report.render_pngs(other, tmp_path / "other", roles=("report_pressure_png",))
    report._BODY_RASTERS.clear()
    (tmp_path / "other-anew").mkdir()
    fresh = report.render_pngs(other, tmp_path / "other-anew", roles=("report_pressure_png",))
    assert drawn["report_pressure_png"].read_bytes() == fresh["report_pressure_png"].read_bytes() != kept["report_pressure_png"].read_bytes()


def test_comparison_only_with_a_baseline(tmp_path):
    files = report.ReportPngExporter().export(plain_result(), tmp_path)
    assert set(files) == {"report_pressure_png", "report_cage_png", "report_surface_png"}
    assert not (tmp_path / "comparison.png").exists()


def test_contact_scale_reaches_the_peak_of_every_design_it_compares():
    ours = np.concatenate([np.zeros(100), np.linspace(100, 1000, 1000), [7400.0]])
    baseline = np.concatenate([np.zeros(100), np.linspace(100, 2000, 1000), [10300.0]])
    assert report.contact_scale(ours) == 7400.0
    assert report.contact_scale(ours, baseline) == 10300.0  # never below either peak
    assert report.contact_scale(ours, None) == 7400.0
    assert report.contact_scale(None) == 0.0
    assert report.contact_scale(np.full(5, 0.5)) == 0.0  # below LOADED_PRESSURE: nothing loaded


def test_comparison_png_scale_covers_both_peaks(pngs):
    res = evaluated_result()
    peaks = [res.contact_pressures[0].pressure.max(), res.baseline.contact_pressures[0].pressure.max()]
    scene = report._scene(res)
    assert report.contact_scale(scene.contact, scene.baseline_contact) == pytest.approx(max(peaks))
    # the bar's dark end (the top) is the scale's darkest colour, and it stands for that peak
    bar = report._colorbar(report.PANEL_HEIGHT, max(peaks), "kPa")
    top = np.asarray(bar)[31, 12]
    assert np.abs(top - np.round(255 * report._colorscale_stops()[1][-1])).max() <= 2


def test_table_rows_name_each_persons_pose_body_and_mass():
    from types import SimpleNamespace

    bodies = [SimpleNamespace(name="default-male:upright-sitting", mass=75.0), SimpleNamespace(name="me.glb:lounger", mass=60.4)]
    labels = report.person_labels(bodies)
    assert labels == ["person 1: upright-sitting, default-male, 75 kg", "person 2: lounger, me.glb, 60 kg"]
    metrics = {"ours": [{"avg_distance_m": 0.04}, {"avg_distance_m": 0.0642}], "baseline": [{}, {}]}
    rows, names = report.table_rows(metrics, labels)
    assert [r[0] for r in rows] == labels
    assert rows[1][1][0] == "6.42 cm" and rows[1][2][0] == "-"
    assert names == ["avg. dist.", "avg. moment", "max. moment", "avg. press.", "max. press.", "max. penetration", "max. body depth"]
    assert [r[0] for r in report.table_rows(metrics)[0]] == ["person 1", "person 2"]


def test_seatkit_pressure_png_is_the_builds_pressure_png(tmp_path):
    from seatkit.export.pressure import write_pressure_png

    res = evaluated_result()
    body, field = res.bodies[0], res.pressures[0]
    alone = write_pressure_png(tmp_path / "alone.png", body, field)
    built = report._pressure_png(report._scene(res), tmp_path / "built.png")
    assert alone.read_bytes() == built.read_bytes()  # the same picture, byte for byte
    img = _rgb(alone)
    # three views, then the bar: light (0 Pa) at the bottom, the darkest colour at the top (the peak)
    assert img.shape[1] == 3 * report.PANEL_WIDTH + 92
    pos, stops = report._colorscale_stops()
    bar = img[:, 3 * report.PANEL_WIDTH :]
    top, bottom = 34 + 22 + 31, 34 + 22 + report.PANEL_HEIGHT - 31
    assert np.abs(bar[top, 12] - np.round(255 * stops[-1])).max() <= 2
    assert np.abs(bar[bottom, 12] - np.round(255 * stops[0])).max() <= 2


def _cube_scene():
    """A unit cube as the cage, and a small body far from it."""
    from types import SimpleNamespace

    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    tet = np.array([[5, 5, 5], [5.1, 5, 5], [5, 5.1, 5], [5, 5, 5.1]])
    tfaces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    body = report._Mesh(tet, tfaces, report.vertex_normals(tet, tfaces), closed=True)
    return report._Scene(
        body=body, importance=np.zeros(4), contact=None, surface=None, cage=SimpleNamespace(vertices=v, faces=quads),
        baseline_surface=None, baseline_contact=None, baseline_cage=None, baseline_name="", metrics={},
    ), v


def test_cage_edges_behind_the_cages_own_faces_are_not_drawn():
    from PIL import Image

    scene, v = _cube_scene()
    report.VIEWS["test-cube"] = (35.0, 20.0)
    try:
        frame = scene.frame("test-cube", "scene")
        img = Image.new("RGB", (frame.width, frame.height), (255, 255, 255))
        report._draw_cage(img, scene, "cage", "test-cube", "scene")
        px = np.asarray(img).astype(int)
        xy, depth = frame.project(v)
    finally:
        del report.VIEWS["test-cube"]
    # seen from the front, the side and above, the far corner is the one at
    # (0, 0, 0): its three edges are hidden by the cube's faces; the other nine are drawn
    hidden_corner = int(np.argmin(depth))
    assert np.allclose(v[hidden_corner], [0, 0, 0])
    edges = {tuple(sorted((int(a), int(b)))) for q in scene.cage.faces for a, b in zip(q, np.roll(q, -1))}
    drawn = {}
    for a, b in edges:
        pts = [xy[a] * (1 - t) + xy[b] * t for t in np.linspace(0.3, 0.7, 5)]
        drawn[(a, b)] = all(
            (np.abs(px[int(y) - 1 : int(y) + 2, int(x) - 1 : int(x) + 2] - report.CAGE_EDGE).max(axis=-1) <= 40).any() for x, y in pts
        )
    hidden = {e for e in edges if hidden_corner in e}
    assert not any(drawn[e] for e in hidden), "an edge behind the cage's own faces was drawn"
    assert all(drawn[e] for e in edges - hidden)


def test_table_rows_never_invent_numbers():
    metrics = {
        "ours": [{"avg_distance_m": 0.012, "supported": True, "avg_pressure_pa": 1500.0, "max_penetration_m": 0.0}],
        "baseline": [{"avg_distance_m": 0.05, "supported": False, "reason": "no contact", "max_penetration_m": 0.0}],
    }
    rows, labels = report.table_rows(metrics)
    (person, ours, base), = rows
    assert labels[0] == "avg. dist." and ours[0] == "1.20 cm" and base[0] == "5.00 cm"
    assert ours[labels.index("avg. press.")] == "1500.00 Pa"
    assert ours[labels.index("max. moment")] == "-"
    assert base[labels.index("avg. press.")] == "not supported"


# ----------------------------------------------------------------------------- HTML


def _decode(spec):
    return np.frombuffer(base64.b64decode(spec["bdata"]), dtype=np.dtype(spec["dtype"]).newbyteorder("<"))


def test_html_is_offline_small_and_holds_the_geometry(tmp_path):
    res = evaluated_result()
    path = report.ReportHtmlExporter().export(res, tmp_path)["report_html"]
    text = path.read_text()
    assert path.stat().st_size < 8 * 1024 * 1024
    # plotly.js inline, nothing loaded from elsewhere
    assert "<script src=" not in text and "<link" not in text and "@import" not in text
    assert "Plotly.newPlot" in text and len(re.findall(r"<script", text)) >= 2
    fig = report.figure_dict(res)
    body = fig["data"][0]
    xyz = np.stack([_decode(body[c]) for c in "xyz"], axis=1)
    assert np.abs(xyz - res.bodies[0].vertices).max() <= 0.5e-3 + 1e-6  # rounded to mm
    ijk = np.stack([_decode(body[c]) for c in "ijk"], axis=1)
    assert np.array_equal(ijk, res.bodies[0].faces)
    kpa = _decode(body["intensity"])
    assert np.allclose(kpa, res.contact_pressures[0].pressure / 1000, atol=1e-3)
    names = [t["name"] for t in fig["data"]]
    assert any("flat-patch" in n for n in names)
    # the table of the paper's quantities, ours and the baseline
    assert "avg. dist." in text and "flat-patch" in text


def test_figure_is_valid_plotly():
    go = pytest.importorskip("plotly.graph_objects")
    fig = report.figure_dict(evaluated_result())
    # plotly.py validates every property; typed arrays are given as lists here
    for trace in fig["data"]:
        for key, val in list(trace.items()):
            if isinstance(val, dict) and "bdata" in val:
                trace[key] = _decode(val).tolist()
    go.Figure(json.loads(json.dumps(fig)))


def test_html_without_evaluation_says_so(tmp_path):
    path = report.write_report_html(plain_result(), tmp_path / "report.html")
    text = path.read_text()
    assert "No evaluation in this build" in text
    fig = report.figure_dict(plain_result())
    assert [t["type"] for t in fig["data"]] == ["mesh3d", "mesh3d", "scatter3d"]
    assert "updatemenus" not in fig["layout"]


def test_exporters_follow_the_protocol():
    from seatkit.interfaces import Exporter

    names = [e.name for e in report.report_exporters()]
    assert names == ["report-png", "report-html"]
    for e in report.report_exporters():
        assert isinstance(e, Exporter) and e.description


def test_html_body_shows_the_contact_on_the_skin_and_the_view_fits_the_window(tmp_path):
    from seatkit.evaluate import LOADED_PRESSURE

    res = evaluated_result()
    fig = report.figure_dict(res)
    body = fig["data"][0]
    kpa = _decode(body["intensity"])
    contact = res.contact_pressures[0].pressure
    assert np.all(kpa[contact <= LOADED_PRESSURE] == 0.0) and np.all(kpa[contact > LOADED_PRESSURE] > 0.0)
    skin = "rgb({},{},{})".format(*(int(round(255 * c)) for c in report.BODY_RGB))
    scale = body["colorscale"]
    assert scale[0] == [0.0, skin]  # no contact: the body's colour, not the scale's light end
    assert 0.0 < scale[1][0] <= 0.02 and scale[-1][0] == 1.0
    assert body["cmax"] >= kpa.max()  # the scale reaches the peak
    text = report.write_report_html(res, tmp_path / "report.html").read_text()
    assert "#view-box { width: 100%; max-width: 960px; height: clamp(420px, 72vh, 760px); }" in text
    assert "person 1: " in text and ", 75 kg" in text


def test_html_time_table_gets_the_export_stage_and_the_total(tmp_path):
    res = evaluated_result()
    path = report.write_report_html(res, tmp_path / "report.html")
    timings = {"bodies": 0.1, "template": 1.0, "baseline (parallel)": 5.0, "export": 2.0}
    assert report.finish_report_html(path, timings)
    text = path.read_text()
    assert "<tr><td>export</td><td>2.000</td></tr>" in text
    assert "<tr><th>total</th><th>3.100</th></tr>" in text  # the parallel stage is not added
    assert text.count("Time per stage") == 1 and "Plotly.newPlot" in text


def test_seatkit_pressure_ply_has_the_builds_body_ply_colours(tmp_path):
    from seatkit.export.meshes import pressure_colors
    from seatkit.export.pressure import write_ply

    res = evaluated_result()
    body, field = res.bodies[0], res.pressures[0]
    data = write_ply(tmp_path / "pressure.ply", body, field).read_bytes()
    head, _, rest = data.partition(b"end_header\n")
    n = len(body.vertices)
    vertex = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("pressure", "<f4")])
    verts = np.frombuffer(rest[: n * vertex.itemsize], dtype=vertex)
    rgb = np.stack([verts["red"], verts["green"], verts["blue"]], axis=1)
    assert np.array_equal(rgb, pressure_colors(field.pressure)[:, :3])
    assert np.allclose(verts["pressure"], field.pressure.astype(np.float32))
