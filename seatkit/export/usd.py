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
from seatkit.messages import clip

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


#: Most faces, face-vertex indices, vertices and crease indices of a USD cage
#: read (a cage of about a million faces, as for OBJ cages).
MAX_USD_ELEMENTS = 10_000_000
#: Most vertices of one face of a USD cage (an n-gon of a furniture cage has a few).
MAX_FACE_SIZE = 64
#: Accepted ``metersPerUnit`` of a stage (from micrometres to kilometres).
METERS_PER_UNIT_RANGE = (1e-6, 1e3)


def _usd_array(attr, path, prim, name: str, dtype, *, width: int | None = None) -> np.ndarray:
    """An attribute's value as a checked numpy array: 1-D (or (n, width)), finite, at most MAX_USD_ELEMENTS rows."""
    value = attr.Get() if attr else None
    if value is None:
        return np.zeros((0,) if width is None else (0, width), dtype)
    try:
        a = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError, OverflowError) as e:
        msg = f"{path}:{prim.GetPath()}: {name}: expected {'numbers' if width is None else f'{width}-vectors'} ({e})"
        raise InputError(msg) from None
    shape_ok = a.ndim == 1 if width is None else (a.ndim == 2 and a.shape[1] == width) or a.size == 0
    if not shape_ok:
        msg = f"{path}:{prim.GetPath()}: {name}: expected {'a list of numbers' if width is None else f'a list of {width}-vectors'}, got shape {a.shape}"
        raise InputError(msg)
    if len(a) > MAX_USD_ELEMENTS:
        msg = f"{path}:{prim.GetPath()}: {name}: {len(a):,} values; seatkit reads cages of at most {MAX_USD_ELEMENTS:,}"
        raise InputError(msg)
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        msg = f"{path}:{prim.GetPath()}: {name}: expected finite numbers, got NaN or infinity"
        raise InputError(msg)
    return a.reshape(-1) if width is None else a.reshape(-1, width)


def _usd_creases(path, prim, c_idx, c_len, c_sharp, n: int):
    """Crease edges (c, 2) and sharpness (c,) of USD's chains, checked and vectorised."""
    where = f"{path}:{prim.GetPath()}"
    if len(c_len) == 0 and len(c_idx) == 0:
        return np.zeros((0, 2), np.int64), np.zeros(0)
    if (c_len < 2).any() or int(c_len.sum()) != len(c_idx):
        msg = (
            f"{where}: creaseLengths: expected chains of at least 2 vertices summing to the "
            f"{len(c_idx)} creaseIndices, got lengths summing to {int(c_len.sum()) if (c_len >= 0).all() else 'a negative total'}"
        )
        raise InputError(msg)
    if ((c_idx < 0) | (c_idx >= n)).any():
        msg = f"{where}: creaseIndices: expected vertex indices from 0 to {n - 1}"
        raise InputError(msg)
    n_edges = int((c_len - 1).sum())
    if len(c_sharp) == len(c_len):
        per_edge = False
    elif len(c_sharp) == n_edges:
        per_edge = True
    else:
        msg = f"{where}: creaseSharpnesses: expected {len(c_len)} (one per crease) or {n_edges} (one per edge) values, got {len(c_sharp)}"
        raise InputError(msg)
    # every index but the last of each chain starts an edge to the next one
    last = np.cumsum(c_len) - 1
    starts = np.setdiff1d(np.arange(len(c_idx)), last)
    edges = np.stack([c_idx[starts], c_idx[starts + 1]], axis=1)
    sharp = c_sharp if per_edge else np.repeat(c_sharp, c_len - 1)
    return edges, np.asarray(sharp, dtype=np.float64)


def _problem(e: Exception) -> str:
    """What usd-core said, on one line (its ``str()`` itself fails on non-UTF-8 text)."""
    try:  # a Tf.ErrorException holds Tf.Error objects: their commentary is what went wrong
        first = e.args[0] if e.args else None
        text = " ".join(str(getattr(first, "commentary", None) or e).split())
    except Exception:  # noqa: BLE001 - Tf.ErrorException.__str__ decodes the file's bytes
        text = ""
    return clip(f"{type(e).__name__}: {text}" if text else type(e).__name__, 200)


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

    Raises
    ------
    InputError
        One line naming the file (and prim and attribute): not a regular file
        or larger than ``MAX_FILE_BYTES["USD"]``, a layer usd-core cannot
        parse, a layer that composes other files (sublayers, references,
        payloads: seatkit reads self-contained cages), counts, indices,
        creases or corners that do not fit the points, non-finite values.
    """
    from seatkit.export.meshes import MAX_CAGE_COORDINATE
    from seatkit.io import MAX_FILE_BYTES, check_user_file
    from seatkit.subdivision import Cage

    Gf, Sdf, Usd, UsdGeom, Vt = _pxr()
    path = Path(path)
    check_user_file(path, "USD file", max_bytes=MAX_FILE_BYTES["USD"])
    from pxr import UsdUtils

    # usd-core's warnings about a user's file ("Integer literal ... out of
    # range") are collected here, not printed: the refusal is one line
    quiet = UsdUtils.CoalescingDiagnosticDelegate()  # noqa: F841 - active while it lives
    try:
        # an anonymous copy of the file: not cached in the layer registry,
        # and its composition arcs are looked at before any other file is opened
        layer = Sdf.Layer.OpenAsAnonymous(str(path))
        deps = sorted(layer.GetCompositionAssetDependencies()) if layer is not None else []
    except (RuntimeError, ValueError) as e:  # pxr.Tf.ErrorException; UnicodeDecodeError of non-UTF-8 text
        msg = f"{path}: usd-core cannot read this file: {_problem(e)}"
        raise InputError(msg) from None
    if layer is None:
        msg = f"{path}: usd-core cannot open this file"
        raise InputError(msg)
    if deps:
        msg = f"{path}: refers to other files ({', '.join(map(str, deps[:3]))}); seatkit reads self-contained USD cages"
        raise InputError(msg)
    try:
        stage = Usd.Stage.Open(layer, Usd.Stage.LoadNone)
        return _read_stage_cage(stage, path, prim_path, Cage, UsdGeom, MAX_CAGE_COORDINATE)
    except (RuntimeError, ValueError) as e:  # pxr.Tf.ErrorException from an attribute of the wrong type; bad UTF-8
        msg = f"{path}: usd-core cannot read this cage: {_problem(e)}"
        raise InputError(msg) from None


def _read_stage_cage(stage, path: Path, prim_path, Cage, UsdGeom, max_coordinate: float):
    """:func:`read_usd_cage` on an open stage."""
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
    where = f"{path}:{prim.GetPath()}"
    mesh = UsdGeom.Mesh(prim)
    pts = _usd_array(mesh.GetPointsAttr(), path, prim, "points", np.float64, width=3)
    xf = np.asarray(UsdGeom.XformCache().GetLocalToWorldTransform(prim), dtype=np.float64)
    meters = float(UsdGeom.GetStageMetersPerUnit(stage))
    lo, hi = METERS_PER_UNIT_RANGE
    if not lo <= meters <= hi:  # NaN fails too
        msg = f"{path}: metersPerUnit: expected {lo:g} to {hi:g}, got {meters:g}"
        raise InputError(msg)
    with np.errstate(all="ignore"):
        pts = (pts @ xf[:3, :3] + xf[3, :3]) * meters
    if not (np.isfinite(pts).all() and (np.abs(pts) <= max_coordinate).all()):
        msg = (
            f"{where}: points: coordinates in metres (after the prim's transforms and metersPerUnit) must be "
            f"finite and within +-{max_coordinate:g}"
        )
        raise InputError(msg)
    counts = _usd_array(mesh.GetFaceVertexCountsAttr(), path, prim, "faceVertexCounts", np.int64)
    idx = _usd_array(mesh.GetFaceVertexIndicesAttr(), path, prim, "faceVertexIndices", np.int64)
    if len(counts) == 0:
        msg = f"{where}: faceVertexCounts: the mesh has no faces"
        raise InputError(msg)
    if ((counts < 3) | (counts > MAX_FACE_SIZE)).any():
        k = int(np.flatnonzero((counts < 3) | (counts > MAX_FACE_SIZE))[0])
        msg = f"{where}: faceVertexCounts[{k}]: expected a face of 3 to {MAX_FACE_SIZE} vertices, got {counts[k]}"
        raise InputError(msg)
    if counts.sum() != len(idx):
        msg = f"{where}: faceVertexCounts sum to {counts.sum()} but there are {len(idx)} indices"
        raise InputError(msg)
    if ((idx < 0) | (idx >= len(pts))).any():
        msg = f"{where}: faceVertexIndices: expected vertex indices from 0 to {len(pts) - 1}"
        raise InputError(msg)
    polys = np.split(idx, np.cumsum(counts)[:-1])
    if mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
        polys = [p[::-1] for p in polys]

    edges, sharp = _usd_creases(
        path,
        prim,
        _usd_array(mesh.GetCreaseIndicesAttr(), path, prim, "creaseIndices", np.int64),
        _usd_array(mesh.GetCreaseLengthsAttr(), path, prim, "creaseLengths", np.int64),
        _usd_array(mesh.GetCreaseSharpnessesAttr(), path, prim, "creaseSharpnesses", np.float64),
        len(pts),
    )
    corners = _usd_array(mesh.GetCornerIndicesAttr(), path, prim, "cornerIndices", np.int64)
    corner_s = _usd_array(mesh.GetCornerSharpnessesAttr(), path, prim, "cornerSharpnesses", np.float64)
    ib = mesh.GetInterpolateBoundaryAttr().Get()
    boundary = "edge-only" if ib in ("edgeOnly", "none") else "edge-and-corner"
    try:
        return Cage(
            pts,
            polys,
            crease_edges=edges,
            crease_sharpness=sharp,
            corners=corners,
            corner_sharpness=corner_s,
            boundary=boundary,
        )
    except InputError as exc:
        msg = f"{where}: {exc}"
        raise InputError(msg) from exc
