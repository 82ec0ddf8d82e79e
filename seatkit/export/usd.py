"""USD export and import of subdivision cages (usd-core, ``pxr``).

The cage becomes a ``UsdGeom.Mesh`` that OpenSubdiv-based tools (usdview,
Houdini, Maya, Blender with ``import_subdivision=True``) evaluate as the same
Catmull-Clark surface seatkit computes: ``subdivisionScheme = catmullClark``,
``interpolateBoundary = edgeAndCorner``, ``faceVaryingLinearInterpolation =
cornersPlus1`` (USD's and OpenSubdiv's defaults, written explicitly), the
creases (``creaseIndices``/``creaseLengths``/``creaseSharpnesses``, one
two-vertex crease per edge) and corners (``cornerIndices``/
``cornerSharpnesses``) with OpenSubdiv sharpness, ``extent``. Uniform int
primvars ``bodySegment`` and ``person`` hold each face's body segment and
person (-1: structural). The posed bodies are further meshes, coloured by
pressure (``displayColor``, vertex) with the pressure itself in Pa as the
float primvar ``pressure``. Stage: ``metersPerUnit = 1``, ``upAxis = Y``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from seatkit.errors import InputError, SeatkitError
from seatkit.io import atomic_path

__all__ = ["write_usd", "read_usd_cage", "prepare_usd", "CAGE_PRIM", "ROOT_PRIM"]

ROOT_PRIM = "/seatkit"
CAGE_PRIM = "/seatkit/Cage"
BODIES_PRIM = "/seatkit/Bodies"

_USD_BOUNDARY = {"edge-and-corner": "edgeAndCorner", "edge-only": "edgeOnly"}


def _pxr():
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, Vt
    except ImportError as exc:  # pragma: no cover - usd-core is a dependency
        msg = "writing USD needs the package 'usd-core', a dependency of seatkit that is missing: pip install 'usd-core>=24.0'"
        raise SeatkitError(msg) from exc
    return Gf, Sdf, Usd, UsdGeom, Vt


def prepare_usd() -> None:
    """Import usd-core and load its plugins (the first stage does), ahead of :func:`write_usd`."""
    Gf, Sdf, Usd, UsdGeom, Vt = _pxr()
    Usd.Stage.CreateInMemory()


def _polygons(mesh):
    if hasattr(mesh, "polygons"):
        polys = mesh.polygons
    else:
        polys = list(np.asarray(mesh.faces, dtype=np.int64))
    counts = np.array([len(p) for p in polys], dtype=np.int32)
    indices = np.concatenate(polys).astype(np.int32)
    return counts, indices


def _define_mesh(stage, path, vertices, counts, indices):
    Gf, Sdf, Usd, UsdGeom, Vt = _pxr()
    mesh = UsdGeom.Mesh.Define(stage, path)
    pts = np.asarray(vertices, dtype=np.float64)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(indices))
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    return mesh


def write_usd(
    path,
    mesh,
    *,
    bodies=(),
    pressures=(),
    boundary: str = "edge-and-corner",
    face_segments=None,
    face_person=None,
) -> Path:
    """Write a cage (and optionally the posed bodies) to .usda or .usdc.

    Parameters
    ----------
    path : str or Path
        ``.usda`` (text) or ``.usdc`` (binary crate); ``.usd`` is crate.
    mesh : ControlMesh or Cage
        The cage; creases and corners are written with their sharpness.
    bodies : sequence of Body
        Posed bodies, written as meshes under ``/seatkit/Bodies``.
    pressures : sequence of PressureField or (n,) arrays
        Pressure of each body (colours and the ``pressure`` primvar).
    boundary : {"edge-and-corner", "edge-only"}
        ``interpolateBoundary`` of the cage.
    face_segments, face_person : (f,) int64, optional
        Per-face primvars; default from the ControlMesh, else -1.

    Returns
    -------
    Path
    """
    from seatkit.export.meshes import pressure_colors

    Gf, Sdf, Usd, UsdGeom, Vt = _pxr()
    path = Path(path)
    if path.suffix.lower() not in (".usda", ".usdc", ".usd"):
        msg = f"{path}: a USD file must end in .usda, .usdc or .usd"
        raise InputError(msg)
    if boundary not in _USD_BOUNDARY:
        msg = f"boundary must be one of {tuple(_USD_BOUNDARY)}, got {boundary!r}"
        raise InputError(msg)
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, ROOT_PRIM)
    stage.SetDefaultPrim(root.GetPrim())
    root.GetPrim().SetCustomDataByKey("seatkit:description", "seat cage (Catmull-Clark) and posed bodies")

    counts, indices = _polygons(mesh)
    cage = _define_mesh(stage, CAGE_PRIM, mesh.vertices, counts, indices)
    cage.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark)
    cage.CreateInterpolateBoundaryAttr(_USD_BOUNDARY[boundary])
    cage.CreateFaceVaryingLinearInterpolationAttr(UsdGeom.Tokens.cornersPlus1)
    cage.CreateTriangleSubdivisionRuleAttr(UsdGeom.Tokens.catmullClark)
    ce = np.asarray(getattr(mesh, "crease_edges", np.zeros((0, 2))), dtype=np.int32).reshape(-1, 2)
    if len(ce):
        cs = np.asarray(mesh.crease_sharpness, dtype=np.float32)
        cage.CreateCreaseIndicesAttr(Vt.IntArray.FromNumpy(ce.reshape(-1)))
        cage.CreateCreaseLengthsAttr(Vt.IntArray.FromNumpy(np.full(len(ce), 2, np.int32)))
        cage.CreateCreaseSharpnessesAttr(Vt.FloatArray.FromNumpy(cs))
    co = np.asarray(getattr(mesh, "corners", np.zeros(0)), dtype=np.int32).reshape(-1)
    if len(co):
        cage.CreateCornerIndicesAttr(Vt.IntArray.FromNumpy(co))
        cage.CreateCornerSharpnessesAttr(
            Vt.FloatArray.FromNumpy(np.asarray(mesh.corner_sharpness, dtype=np.float32))
        )
    nf = len(counts)
    seg = face_segments if face_segments is not None else getattr(mesh, "face_segments", None)
    per = face_person if face_person is not None else getattr(mesh, "face_person", None)
    api = UsdGeom.PrimvarsAPI(cage)
    for name, values in (("bodySegment", seg), ("person", per)):
        arr = np.full(nf, -1, np.int32) if values is None else np.asarray(values, dtype=np.int32)
        if arr.shape != (nf,):
            msg = f"{name} must have one value per cage face ({nf}), got shape {arr.shape}"
            raise InputError(msg)
        pv = api.CreatePrimvar(name, Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform)
        pv.Set(Vt.IntArray.FromNumpy(arr))
    labels = getattr(mesh, "face_labels", None)
    if labels is not None and len(labels) == nf:
        pv = api.CreatePrimvar("faceLabel", Sdf.ValueTypeNames.StringArray, UsdGeom.Tokens.uniform)
        pv.Set(Vt.StringArray([str(s) for s in labels]))
    cage.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(Vt.Vec3fArray([Gf.Vec3f(0.72, 0.62, 0.48)]))

    if len(bodies):
        UsdGeom.Scope.Define(stage, BODIES_PRIM)
    for i, body in enumerate(bodies):
        tri = np.asarray(body.faces, dtype=np.int32)
        bm = _define_mesh(
            stage, f"{BODIES_PRIM}/Body_{i}", body.vertices, np.full(len(tri), 3, np.int32), tri.reshape(-1)
        )
        bm.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        if i < len(pressures) and pressures[i] is not None:
            p = np.asarray(getattr(pressures[i], "pressure", pressures[i]), dtype=np.float64)
            if p.shape != (len(body.vertices),):
                msg = f"pressure {i} must have one value per body vertex ({len(body.vertices)}), got {p.shape}"
                raise InputError(msg)
            rgb = pressure_colors(p)[:, :3].astype(np.float32) / 255.0
            bm.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex).Set(Vt.Vec3fArray.FromNumpy(rgb))
            pv = UsdGeom.PrimvarsAPI(bm).CreatePrimvar("pressure", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex)
            pv.Set(Vt.FloatArray.FromNumpy(p.astype(np.float32)))
            pv.GetAttr().SetDocumentation("contact pressure, Pa")
        if getattr(body, "name", ""):
            bm.GetPrim().SetCustomDataByKey("seatkit:name", str(body.name))

    with atomic_path(path) as tmp:
        if not stage.GetRootLayer().Export(str(tmp)):
            msg = f"{path}: usd-core could not write the file"
            raise InputError(msg)
    return path


def read_usd_cage(path, *, prim_path: str | None = None):
    """Read a Catmull-Clark cage (creases, corners, boundary mode) from a USD file.

    Parameters
    ----------
    path : str or Path
    prim_path : str, optional
        The mesh prim; default ``/seatkit/Cage`` if present, else the first
        mesh with ``subdivisionScheme = catmullClark``, else the first mesh.

    Returns
    -------
    seatkit.subdivision.Cage
        Points in world space (the prim's transforms applied), metres if the
        stage says ``metersPerUnit``.
    """
    from seatkit.subdivision import Cage

    Gf, Sdf, Usd, UsdGeom, Vt = _pxr()
    path = Path(path)
    if not path.exists():
        msg = f"{path}: no such USD file"
        raise InputError(msg)
    stage = Usd.Stage.Open(str(path))
    if stage is None:
        msg = f"{path}: usd-core cannot open this file"
        raise InputError(msg)
    prim = None
    if prim_path is not None:
        prim = stage.GetPrimAtPath(prim_path)
        if not prim or not prim.IsA(UsdGeom.Mesh):
            msg = f"{path}: no mesh prim at {prim_path}"
            raise InputError(msg)
    else:
        meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
        if not meshes:
            msg = f"{path}: the stage holds no UsdGeom.Mesh"
            raise InputError(msg)
        cand = [p for p in meshes if str(p.GetPath()) == CAGE_PRIM]
        cand += [p for p in meshes if UsdGeom.Mesh(p).GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.catmullClark]
        prim = (cand or meshes)[0]
    mesh = UsdGeom.Mesh(prim)
    pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
    xf = np.asarray(UsdGeom.XformCache().GetLocalToWorldTransform(prim), dtype=np.float64)
    pts = pts @ xf[:3, :3] + xf[3, :3]
    pts *= UsdGeom.GetStageMetersPerUnit(stage)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), dtype=np.int64)
    idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int64)
    if counts.sum() != len(idx):
        msg = f"{path}:{prim.GetPath()}: faceVertexCounts sum to {counts.sum()} but there are {len(idx)} indices"
        raise InputError(msg)
    polys = np.split(idx, np.cumsum(counts)[:-1])
    if mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
        polys = [p[::-1] for p in polys]

    edges, sharp = [], []
    c_idx = mesh.GetCreaseIndicesAttr().Get()
    if c_idx:
        c_idx = np.asarray(c_idx, dtype=np.int64)
        c_len = np.asarray(mesh.GetCreaseLengthsAttr().Get(), dtype=np.int64)
        c_sharp = np.asarray(mesh.GetCreaseSharpnessesAttr().Get(), dtype=np.float64)
        per_edge = len(c_sharp) == int((c_len - 1).sum()) and len(c_sharp) != len(c_len)
        start = 0
        k = 0
        for i, n in enumerate(c_len.tolist()):
            chain = c_idx[start : start + n]
            for j in range(n - 1):
                edges.append(chain[j : j + 2])
                sharp.append(c_sharp[k] if per_edge else c_sharp[i])
                k += 1
            start += n
    corners = mesh.GetCornerIndicesAttr().Get()
    corner_s = mesh.GetCornerSharpnessesAttr().Get()
    ib = mesh.GetInterpolateBoundaryAttr().Get()
    boundary = "edge-only" if ib in ("edgeOnly", "none") else "edge-and-corner"
    try:
        return Cage(
            pts,
            polys,
            crease_edges=np.array(edges, dtype=np.int64).reshape(-1, 2),
            crease_sharpness=np.array(sharp, dtype=np.float64),
            corners=np.asarray(corners if corners else [], dtype=np.int64),
            corner_sharpness=np.asarray(corner_s if corner_s else [], dtype=np.float64),
            boundary=boundary,
        )
    except InputError as exc:
        msg = f"{path}:{prim.GetPath()}: {exc}"
        raise InputError(msg) from exc
