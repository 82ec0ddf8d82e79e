"""Exporters: USD round trip and validation, OBJ cage, surface formats,
watertight shell, pressure-coloured body."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import trimesh

from seatkit.errors import InputError
from seatkit.export.exporters import builtin_exporters
from seatkit.export.meshes import read_obj_cage, thick_shell, write_cage_obj, write_surface
from seatkit.export.usd import CAGE_PRIM, read_usd_cage, write_usd
from seatkit.interfaces import Exporter
from seatkit.model import Body, BuildResult, ControlMesh, PressureField
from seatkit.subdivision import Cage, build_operators, limit_surface

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom  # noqa: E402

_spec = importlib.util.spec_from_file_location(
    "seatkit_tests_osd_fixtures", Path(__file__).parent / "osd_reference" / "fixtures.py"
)
_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_fixtures)
runner = _fixtures.load_runner()


def _control_mesh():
    v, f, crease = runner.chair_cage()
    nf = len(f)
    seg = np.where(np.arange(nf) < 63, np.arange(nf) % 21, -1)
    return ControlMesh(
        vertices=v,
        faces=np.array(f),
        face_segments=seg,
        face_person=np.where(seg >= 0, 0, -1),
        face_labels=tuple("seat" if s >= 0 else "border" for s in seg),
        crease_edges=np.array(crease),
        crease_sharpness=np.full(len(crease), 2.5),
        corners=np.array([0]),
        corner_sharpness=np.array([10.0]),
    )


def _body():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    verts = sphere.vertices + [0, 0.7, 0.2]
    n = len(verts)
    body = Body(
        vertices=verts,
        faces=np.asarray(sphere.faces, dtype=np.int64),
        weights=np.full((n, 21), 1 / 21),
        joints=np.zeros((21, 3)),
        tips=np.zeros((21, 3)),
        segment_mass=np.full(21, 75 / 21),
        segment_com=np.zeros((21, 3)),
        name="sphere",
    )
    pressure = np.clip(0.7 - verts[:, 1], 0, None) * 1e4
    field = PressureField(
        force=np.zeros((n, 3)),
        normal_force=pressure * 1e-4,
        pressure=pressure,
        shear=np.zeros(n),
        area=np.full(n, 1e-4),
        contact=pressure > 0,
        joint_force=np.zeros((20, 3)),
        joint_moment=np.zeros((20, 3)),
    )
    return body, field


@pytest.fixture(scope="module")
def result():
    cm = _control_mesh()
    body, field = _body()
    return BuildResult(
        recipe={"surface_level": 2},
        bodies=[body],
        pressures=[field],
        initial_mesh=cm,
        control_mesh=cm,
        surface=limit_surface(cm, level=2),
    )


@pytest.mark.parametrize("suffix", [".usda", ".usdc"])
def test_usd_round_trip_and_validation(tmp_path, result, suffix):
    cm = result.control_mesh
    path = write_usd(tmp_path / f"seat{suffix}", cm, bodies=result.bodies, pressures=result.pressures)
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == "/seatkit"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(CAGE_PRIM))
    assert mesh.GetSubdivisionSchemeAttr().Get() == "catmullClark"
    assert mesh.GetInterpolateBoundaryAttr().Get() == "edgeAndCorner"
    assert mesh.GetFaceVaryingLinearInterpolationAttr().Get() == "cornersPlus1"
    ok, why = UsdGeom.Mesh.ValidateTopology(
        mesh.GetFaceVertexIndicesAttr().Get(), mesh.GetFaceVertexCountsAttr().Get(), len(mesh.GetPointsAttr().Get())
    )
    assert ok, why
    idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get())
    pts = np.asarray(mesh.GetPointsAttr().Get())
    assert ok, why
    np.testing.assert_array_equal(idx.reshape(-1, 4), cm.faces)
    np.testing.assert_allclose(pts, cm.vertices, atol=1e-6)
    ext = np.asarray(mesh.GetExtentAttr().Get())
    np.testing.assert_allclose(ext, [cm.vertices.min(0), cm.vertices.max(0)], atol=1e-6)
    assert list(mesh.GetCreaseLengthsAttr().Get()) == [2] * len(cm.crease_edges)
    np.testing.assert_array_equal(np.asarray(mesh.GetCreaseIndicesAttr().Get()).reshape(-1, 2), cm.crease_edges)
    np.testing.assert_allclose(mesh.GetCreaseSharpnessesAttr().Get(), 2.5)
    assert list(mesh.GetCornerIndicesAttr().Get()) == [0]
    api = UsdGeom.PrimvarsAPI(mesh)
    seg = api.GetPrimvar("bodySegment")
    assert seg.GetInterpolation() == UsdGeom.Tokens.uniform
    np.testing.assert_array_equal(seg.Get(), cm.face_segments)
    np.testing.assert_array_equal(api.GetPrimvar("person").Get(), cm.face_person)
    body_mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/seatkit/Bodies/Body_0"))
    b_idx = body_mesh.GetFaceVertexIndicesAttr().Get()
    b_cnt = body_mesh.GetFaceVertexCountsAttr().Get()
    ok, why = UsdGeom.Mesh.ValidateTopology(b_idx, b_cnt, len(result.bodies[0].vertices))
    assert ok, why
    colours = body_mesh.GetDisplayColorPrimvar()
    assert colours.GetInterpolation() == UsdGeom.Tokens.vertex
    assert len(colours.Get()) == len(result.bodies[0].vertices)
    p = np.asarray(UsdGeom.PrimvarsAPI(body_mesh).GetPrimvar("pressure").Get())
    np.testing.assert_allclose(p, result.pressures[0].pressure, rtol=1e-6)
    # Highest pressure gets the darkest colour.
    c = np.asarray(colours.Get())
    assert c[np.argmax(p)].sum() < c[np.argmin(p)].sum()

    # Reading the cage back gives the same subdivision surface.
    cage = read_usd_cage(path)
    assert cage.boundary == "edge-and-corner"
    ref = Cage.from_control_mesh(cm)
    np.testing.assert_allclose(cage.crease_sharpness, ref.crease_sharpness)
    a = build_operators(cage, 2).limit @ cage.vertices
    b = build_operators(ref, 2).limit @ ref.vertices
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_usd_reader_handles_chains_and_edge_only(tmp_path):
    v, f = runner.grid(4, 4)
    stage = Usd.Stage.CreateNew(str(tmp_path / "chain.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)  # centimetres: read back in metres
    xf = UsdGeom.Xform.Define(stage, "/World")
    xf.AddTranslateOp().Set((1.0, 2.0, 3.0))
    m = UsdGeom.Mesh.Define(stage, "/World/M")
    m.CreatePointsAttr([tuple(p) for p in v])
    m.CreateFaceVertexCountsAttr([4] * len(f))
    m.CreateFaceVertexIndicesAttr([i for q in f for i in q])
    m.CreateSubdivisionSchemeAttr("catmullClark")
    m.CreateInterpolateBoundaryAttr("edgeOnly")
    m.CreateCreaseIndicesAttr([5, 6, 7, 8])  # one chain of three edges
    m.CreateCreaseLengthsAttr([4])
    m.CreateCreaseSharpnessesAttr([1.5])
    stage.Save()
    cage = read_usd_cage(tmp_path / "chain.usda")
    assert cage.boundary == "edge-only"
    assert cage.crease_edges.tolist() == [[5, 6], [6, 7], [7, 8]]
    np.testing.assert_allclose(cage.crease_sharpness, 1.5)
    np.testing.assert_allclose(cage.vertices, (v + [1, 2, 3]) * 0.01, atol=1e-8)


def test_obj_cage_round_trip(tmp_path, result):
    cm = result.control_mesh
    path = write_cage_obj(cm, tmp_path / "cage.obj")
    cage = read_obj_cage(path)
    np.testing.assert_allclose(cage.vertices, cm.vertices, atol=1e-8)
    np.testing.assert_array_equal(cage.faces, cm.faces)
    np.testing.assert_array_equal(cage.crease_edges, cm.crease_edges)
    loaded = trimesh.load(path, process=False, force="mesh")
    assert len(loaded.vertices) == len(cm.vertices)


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".stl", ".glb"])
def test_surface_formats(tmp_path, result, suffix):
    surf = result.surface
    path = write_surface(surf, tmp_path / f"surface{suffix}")
    loaded = trimesh.load(path, process=False, force="mesh")
    assert len(loaded.faces) == 2 * len(surf.faces)
    # Same geometry: every written vertex is a limit point (STL repeats them).
    merged = np.unique(np.round(np.asarray(loaded.vertices), 5), axis=0)
    assert len(merged) == len(surf.vertices)
    assert np.abs(np.sort(merged, axis=0) - np.sort(np.round(surf.vertices, 5), axis=0)).max() < 2e-5
    assert not any(p.name.endswith(".tmp" + suffix) for p in tmp_path.iterdir())


def test_obj_surface_keeps_quads_and_normals(tmp_path, result):
    path = write_surface(result.surface, tmp_path / "s.obj")
    lines = path.read_text().splitlines()
    assert sum(1 for s in lines if s.startswith("vn ")) == len(result.surface.vertices)
    faces = [s for s in lines if s.startswith("f ")]
    assert len(faces) == len(result.surface.faces) and all(len(s.split()) == 5 for s in faces)


@pytest.mark.parametrize("which", ["chair", "cube", "grid"])
def test_thick_shell_is_watertight(which):
    if which == "chair":
        v, f, _ = runner.chair_cage()
    elif which == "cube":
        v, f = runner.cube_cage()
    else:
        v, f = runner.grid(5, 4, bump=0.05)
    surf = limit_surface(Cage(v, f), level=2)
    shell = thick_shell(surf, 0.01)
    assert shell.is_watertight
    assert shell.is_winding_consistent
    if which != "cube":
        # An open sheet thickened by t has volume about t * area.
        area = trimesh.Trimesh(surf.vertices, runner_tris(surf.faces), process=False).area
        assert shell.volume == pytest.approx(0.01 * area, rel=0.1)
    with pytest.raises(InputError, match="thickness must be > 0"):
        thick_shell(surf, 0.0)


def runner_tris(q):
    from seatkit.export.meshes import quads_to_triangles

    return quads_to_triangles(q)


def test_builtin_exporters_write_every_file(tmp_path, result):
    exporters = builtin_exporters()
    assert {e.name for e in exporters} == {"usd", "usdc", "obj", "surface", "shell", "body-ply"}
    written = {}
    for e in exporters:
        assert isinstance(e, Exporter)
        files = e.export(result, tmp_path)
        assert files and all(Path(p).exists() and Path(p).parent == tmp_path for p in files.values())
        written.update(files)
    assert set(written) == {
        "usd", "usdc", "cage_obj", "surface_obj", "surface_ply", "surface_stl", "surface_glb", "shell_stl", "body_ply",
    }
    shell = trimesh.load(written["shell_stl"], force="mesh")
    assert shell.is_watertight
    body = trimesh.load(written["body_ply"], process=False)
    colours = np.asarray(body.visual.vertex_colors)
    assert colours.shape == (len(result.bodies[0].vertices), 4)
    p = result.pressures[0].pressure
    assert colours[np.argmax(p), :3].astype(int).sum() < colours[np.argmin(p), :3].astype(int).sum()
    assert sorted(q.name for q in tmp_path.iterdir() if q.name.startswith(".")) == []


def test_plugin_registers_the_exporters():
    spec = importlib.util.spec_from_file_location(
        "seatkit_exporters_plugin", Path(__file__).parents[1] / "plugins" / "seatkit_exporters" / "__init__.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    names = [e.name for e in mod.seatkit_register_exporters()]
    assert names == ["usd", "usdc", "obj", "surface", "shell", "body-ply", "design", "report-png", "report-html", "structure", "report-json"]


def test_pressure_colours_match_matplotlib_without_importing_it():
    from matplotlib import colormaps

    from seatkit.export.meshes import pressure_colors

    rng = np.random.default_rng(3)
    # every entry of the map, its edges, values between entries, zero, the peak, NaN
    edges = np.nextafter(np.arange(1, 257) / 256.0, 0)
    p = np.concatenate([np.arange(257) / 256.0, edges, rng.uniform(0, 1, 5000), [0.0, 1.0, np.nan]]) * 3200.0
    got = pressure_colors(p)
    peak = np.nanmax(p)
    want = (colormaps["magma_r"](np.clip(p / peak, 0, 1)) * 255).round().astype(np.uint8)
    # max() of an array with NaN is NaN: compare on the finite ones, with the same peak
    finite = np.isfinite(p)
    got_finite = pressure_colors(np.where(finite, p, 0.0))
    assert np.array_equal(got_finite[finite], want[finite])
    assert got.shape == (len(p), 4)
    # another map goes through matplotlib itself
    viridis = (colormaps["viridis"](p[finite] / peak) * 255).round().astype(np.uint8)
    assert np.array_equal(pressure_colors(p[finite], cmap="viridis"), viridis)


@pytest.mark.parametrize("suffix", [".ply", ".stl", ".glb"])
def test_surface_files_are_the_bytes_trimesh_wrote(tmp_path, result, suffix):
    """The PLY, STL and GLB writers replaced trimesh's (whose import cost a build 0.2-0.4 s): same bytes."""
    from seatkit.export.meshes import surface_trimesh

    ours = write_surface(result.surface, tmp_path / f"s{suffix}").read_bytes()
    assert ours == surface_trimesh(result.surface).export(file_type=suffix[1:])
    # and they read back as the same mesh
    back = trimesh.load(tmp_path / f"s{suffix}", force="mesh", process=False)
    if suffix != ".stl":  # STL repeats corners per triangle
        np.testing.assert_allclose(back.vertices, result.surface.vertices, atol=1e-6)


def test_body_ply_is_the_bytes_trimesh_wrote(tmp_path, result):
    from seatkit.export.meshes import pressure_colors, write_body_ply

    body, pressure = result.bodies[0], result.pressures[0]
    from dataclasses import replace

    rng = np.random.default_rng(0)
    interface = replace(pressure, force=rng.normal(size=(len(body.vertices), 3)), pressure=rng.random(len(body.vertices)) * 1e4)
    ours = write_body_ply(body, pressure, tmp_path / "body.ply", interface=interface).read_bytes()
    mesh = trimesh.Trimesh(body.vertices, body.faces, vertex_colors=pressure_colors(pressure.pressure), process=False)
    columns = {
        "importance_pa": pressure.pressure,
        "force_x": interface.force[:, 0],
        "force_y": interface.force[:, 1],
        "force_z": interface.force[:, 2],
        "interface_pa": interface.pressure,
    }
    for name, values in columns.items():
        mesh.vertex_attributes[name] = values.astype(np.float32)
    assert ours == mesh.export(file_type="ply")


def test_stl_normals_of_degenerate_triangles_are_zero():
    from seatkit.export.meshes import stl_bytes

    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]])
    f = np.array([[0, 1, 2], [0, 1, 3]])  # the second is a segment
    data = stl_bytes(v, f)
    rec = np.frombuffer(data[84:], dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("a", "<u2")])
    np.testing.assert_array_equal(rec["n"], [[0, 0, 1], [0, 0, 0]])
    assert data == trimesh.Trimesh(v, f, process=False).export(file_type="stl")
