"""Mesh files: the cage as OBJ, the limit surface as OBJ/PLY/STL/GLB, a
watertight shell of the surface for fabrication, the pressure-coloured body.

Every file is written atomically (a temporary file beside the target, then
``os.replace``), so an interrupted export never leaves half a file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from seatkit.errors import InputError
from seatkit.io import atomic_path, atomic_write, write_bytes_atomic
from seatkit.picture.colour import MAGMA_R_BYTES

__all__ = [
    "SURFACE_FORMATS",
    "glb_bytes",
    "ply_bytes",
    "stl_bytes",
    "read_obj_cage",
    "pressure_colors",
    "quads_to_triangles",
    "surface_trimesh",
    "thick_shell",
    "write_body_ply",
    "write_cage_obj",
    "write_shell",
    "write_surface",
]

#: Largest cage coordinate :func:`read_obj_cage` accepts (100 m in a
#: millimetre export; beyond it the normals' squared lengths lose precision,
#: and 1e308 overflows them to zero).
MAX_CAGE_COORDINATE = 1e5
#: Largest vertex index an OBJ face may name.
MAX_CAGE_INDEX = 10_000_000

#: File suffixes :func:`write_surface` writes.
SURFACE_FORMATS = (".obj", ".ply", ".stl", ".glb")


def _fmt_rows(prefix: str, rows: np.ndarray, fmt: str, per_value: np.ndarray | None = None) -> str:
    """One line ``prefix fmt fmt ...`` per row, ``fmt`` once per column, formatted as one text at once.

    ``per_value``: the values ``fmt`` takes, row by row, when it takes more than one per column.
    """
    rows = np.asarray(rows)
    values = rows if per_value is None else np.asarray(per_value)
    line = prefix + " " + " ".join([fmt] * rows.shape[1]) + "\n"
    return (line * len(rows)) % tuple(values.ravel().tolist())


def write_cage_obj(mesh, path) -> Path:
    """Write a cage (ControlMesh or Cage) as a plain Wavefront OBJ.

    Vertices in metres, faces 1-based, counter-clockwise. OBJ has no crease
    syntax that Blender, Maya or Houdini read, so creases go to the USD file;
    they are listed here as comments only.

    Parameters
    ----------
    mesh : ControlMesh or Cage
    path : str or Path

    Returns
    -------
    Path
    """
    verts = np.asarray(mesh.vertices, dtype=np.float64)
    polys = mesh.polygons if hasattr(mesh, "polygons") else list(np.asarray(mesh.faces))
    out = ["# seatkit subdivision cage (Catmull-Clark control mesh), metres, +Y up\n"]
    out.append(f"# {len(verts)} vertices, {len(polys)} faces\n")
    ce = np.asarray(getattr(mesh, "crease_edges", np.zeros((0, 2))), dtype=np.int64).reshape(-1, 2)
    cs = np.asarray(getattr(mesh, "crease_sharpness", np.zeros(0)), dtype=np.float64)
    for (a, b), s in zip(ce.tolist(), cs.tolist()):
        out.append(f"# crease {a + 1} {b + 1} {s:g}\n")
    out.append(_fmt_rows("v", verts, "%.9g"))
    out.extend("f " + " ".join(str(int(i) + 1) for i in p) + "\n" for p in polys)
    with atomic_write(path, "w") as fh:
        fh.write("".join(out))
    return Path(path)


def read_obj_cage(path):
    """Read the polygons of an OBJ file as a :class:`~seatkit.subdivision.Cage`.

    Reads ``v`` and ``f`` records (``f a/b/c`` forms and negative indices
    too) and the ``# crease a b s`` comments :func:`write_cage_obj` writes.
    """
    from seatkit.subdivision import Cage

    from seatkit.errors import RecipeError
    from seatkit.messages import clip
    from seatkit.yamlio import decode_text

    path = Path(path)
    verts, faces, creases, sharp = [], [], [], []
    from seatkit.io import MAX_FILE_BYTES, read_user_file

    data = read_user_file(path, "OBJ cage", max_bytes=MAX_FILE_BYTES["OBJ"])
    try:
        text = decode_text(data, str(path), "OBJ file")
    except RecipeError as exc:
        raise InputError(str(exc)) from None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        parts = raw.split()
        if not parts:
            continue
        try:
            if parts[0] == "v":
                xyz = [float(x) for x in parts[1:4]]
                if len(xyz) != 3:
                    raise ValueError("a vertex needs x, y and z")
                if not all(abs(x) <= MAX_CAGE_COORDINATE for x in xyz):  # NaN fails too
                    msg = (
                        f"{path}:{lineno}: vertex {len(verts) + 1}: coordinates must be finite and within "
                        f"+-{MAX_CAGE_COORDINATE:g} (m, or mm for a millimetre export), got {clip(' '.join(parts[1:4]))}"
                    )
                    raise InputError(msg)
                verts.append(xyz)
            elif parts[0] == "f":
                idx = [int(tok.split("/")[0]) for tok in parts[1:]]
                if not all(-len(verts) <= i <= MAX_CAGE_INDEX and i != 0 for i in idx):
                    msg = f"{path}:{lineno}: face {len(faces) + 1}: vertex indices must be 1..n or -1..-{len(verts)} (OBJ), got {clip(' '.join(parts[1:]))}"
                    raise InputError(msg)
                faces.append([i - 1 if i > 0 else len(verts) + i for i in idx])
            elif parts[:2] == ["#", "crease"] and len(parts) >= 5:
                a, b, s = int(parts[2]), int(parts[3]), float(parts[4])
                if not (1 <= a <= MAX_CAGE_INDEX and 1 <= b <= MAX_CAGE_INDEX and 0 <= s <= MAX_CAGE_INDEX):
                    msg = (
                        f"{path}:{lineno}: crease: expected two vertex numbers 1..n and a sharpness >= 0 "
                        f"(# crease a b s), got {clip(' '.join(parts[2:5]))}"
                    )
                    raise InputError(msg)
                creases.append([a - 1, b - 1])
                sharp.append(s)
        except ValueError as exc:
            msg = f"{path}:{lineno}: malformed OBJ record {clip(raw.strip())!r}"
            raise InputError(msg) from exc
    if not verts or not faces:
        msg = f"{path}: no vertices or faces in OBJ cage"
        raise InputError(msg)
    try:
        return Cage(np.array(verts), faces, crease_edges=creases or None, crease_sharpness=sharp or None)
    except InputError as exc:
        msg = f"{path}: {exc}"
        raise InputError(msg) from exc


def quads_to_triangles(quads: np.ndarray) -> np.ndarray:
    """(2q, 3) int64 triangles of (q, 4) quads, split along the 0-2 diagonal."""
    q = np.asarray(quads, dtype=np.int64)
    return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]).reshape(2, -1, 3).transpose(1, 0, 2).reshape(-1, 3)


def surface_trimesh(surface):
    """A :class:`trimesh.Trimesh` of a limit surface (its normals kept)."""
    import trimesh

    return trimesh.Trimesh(
        vertices=surface.vertices,
        faces=quads_to_triangles(surface.faces),
        vertex_normals=surface.normals,
        process=False,
    )


def write_surface(surface, path) -> Path:
    """Write a limit surface; the format follows the suffix (.obj .ply .stl .glb).

    OBJ keeps the quads and the limit normals (``vn``); PLY (with the
    normals), STL and GLB (with the normals) are triangle meshes, written by
    :func:`ply_bytes`, :func:`stl_bytes` and :func:`glb_bytes`.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SURFACE_FORMATS:
        msg = f"{path}: unsupported surface format {suffix!r}; expected one of {SURFACE_FORMATS}"
        raise InputError(msg)
    if suffix == ".obj":
        text = [f"# seatkit Catmull-Clark limit surface, level {surface.level}, metres, +Y up\n"]
        text.append(_fmt_rows("v", np.asarray(surface.vertices), "%.9g"))
        text.append(_fmt_rows("vn", np.asarray(surface.normals), "%.7g"))
        f1 = np.asarray(surface.faces, dtype=np.int64) + 1
        text.append(_fmt_rows("f", f1, "%d//%d", per_value=np.repeat(f1, 2, axis=1)))
        with atomic_write(path, "w") as fh:
            fh.write("".join(text))
        return path
    vertices, faces = np.asarray(surface.vertices, dtype=np.float64), quads_to_triangles(surface.faces)
    normals = np.asarray(surface.normals, dtype=np.float64)
    if suffix == ".ply":
        data = ply_bytes(vertices, faces, normals=normals)
    elif suffix == ".stl":
        data = stl_bytes(vertices, faces)
    else:
        data = glb_bytes(vertices, faces, normals=normals)
    return write_bytes_atomic(path, data)


# Binary PLY, STL and GLB of a triangle mesh. These files were written by
# trimesh until its import (0.2-0.4 s) became a large part of a build's time;
# the writers below produce the same bytes trimesh 5.2 does for these meshes
# (a test compares them), header comment included.

_PLY_HEADER = "ply\nformat binary_little_endian 1.0\ncomment https://github.com/mikedh/trimesh\n"


def ply_bytes(vertices: np.ndarray, faces: np.ndarray, *, normals=None, colors=None, scalars=None) -> bytes:
    """A binary little-endian PLY.

    Float32 positions, optional float32 normals and uint8 RGBA colours, then
    one float32 vertex property per entry of ``scalars`` (name -> (n,)
    array, in order), int32 triangles.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    header = [_PLY_HEADER, f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"]
    dtype = [("vertex", "<f4", (3,))]
    if normals is not None:
        header.append("property float nx\nproperty float ny\nproperty float nz\n")
        dtype.append(("normals", "<f4", (3,)))
    if colors is not None:
        header.append("property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n")
        dtype.append(("rgba", "<u1", (4,)))
    for name in scalars or {}:
        header.append(f"property float {name}\n")
        dtype.append((name, "<f4"))
    header.append(f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    vert = np.zeros(len(vertices), dtype=dtype)
    for name, values in (scalars or {}).items():
        vert[name] = np.asarray(values, dtype=np.float64)
    vert["vertex"] = vertices
    if normals is not None:
        vert["normals"] = np.asarray(normals, dtype=np.float64)
    if colors is not None:
        vert["rgba"] = np.asarray(colors, dtype=np.uint8)
    face = np.zeros(len(faces), dtype=[("count", "<u1"), ("index", "<i4", (3,))])
    face["count"] = 3
    face["index"] = faces
    return "".join(header).encode("utf-8") + vert.tobytes() + face.tobytes()


def _unit_rows(vectors: np.ndarray, threshold: float = 1e-13) -> tuple[np.ndarray, np.ndarray]:
    """Rows divided by their length, and which rows were longer than ``threshold`` (the others are not divided)."""
    norm = np.sqrt(np.dot(vectors * vectors, [1.0] * vectors.shape[1]))
    valid = norm > threshold
    norm[valid] **= -1
    return vectors * norm.reshape((-1, 1)), valid


def stl_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A binary STL: an empty 80-byte header, the count, then unit face normal and corners per triangle (float32)."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64).reshape(-1, 3)]
    edges = tri[:, 1:, :] - tri[:, :2, :]
    unit, valid = _unit_rows(np.cross(edges[:, 0], edges[:, 1]))
    normals = np.where(valid[:, None], unit, 0.0)  # degenerate triangles: a zero normal
    header = np.zeros(1, dtype=[("header", np.void, 80), ("face_count", "<u4")])
    header["face_count"] = len(tri)
    packed = np.zeros(len(tri), dtype=[("normals", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attributes", "<u2")])
    packed["normals"] = normals
    packed["vertices"] = tri
    return header.tobytes() + packed.tobytes()


def _pad4(data: bytes, fill: bytes = b"\0") -> bytes:
    return data + fill * (-len(data) % 4)


def glb_bytes(vertices: np.ndarray, faces: np.ndarray, *, normals=None) -> bytes:
    """A binary glTF 2.0 (GLB) of one triangle mesh: uint32 indices, float32 positions and unit normals."""
    import json

    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if not len(faces):
        msg = "a GLB file needs at least one triangle"
        raise InputError(msg)
    # accessors: the keys in the order trimesh wrote them (the JSON's bytes follow it)
    index = faces.astype(np.uint32)
    accessors = [
        {
            "componentType": 5125,
            "type": "SCALAR",
            "bufferView": 0,
            "count": int(index.size),
            "max": [int(index.max())],
            "min": [int(index.min())],
        }
    ]
    position = vertices.astype(np.float32)
    accessors.append(
        {
            "componentType": 5126,
            "type": "VEC3",
            "byteOffset": 0,
            "bufferView": 1,
            "count": len(position),
            "max": position.max(axis=0).tolist(),
            "min": position.min(axis=0).tolist(),
        }
    )
    attributes = {"POSITION": 1}
    blobs = [_pad4(index.tobytes()), _pad4(position.tobytes())]
    if normals is not None:
        unit = _unit_rows(np.asarray(normals, dtype=np.float64))[0].astype(np.float32)
        accessors.append(
            {
                "componentType": 5126,
                "count": len(unit),
                "type": "VEC3",
                "byteOffset": 0,
                "bufferView": 2,
                "max": unit.max(axis=0).tolist(),
                "min": unit.min(axis=0).tolist(),
            }
        )
        attributes["NORMAL"] = 2
        blobs.append(_pad4(unit.tobytes()))
    views, offset = [], 0
    for blob in blobs:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(blob)})
        offset += len(blob)
    tree = {
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "asset": {"version": "2.0", "generator": "https://github.com/mikedh/trimesh"},
        "accessors": accessors,
        "meshes": [
            {"name": "geometry_0", "extras": {}, "primitives": [{"attributes": attributes, "indices": 0, "mode": 4}]}
        ],
        "nodes": [{"name": "geometry_0", "mesh": 0}],
        "buffers": [{"byteLength": offset}],
        "bufferViews": views,
    }
    content = json.dumps(tree, separators=(",", ":"))
    content = (content + (4 - ((len(content) + 20) % 4)) * " ").encode("utf-8")
    binary = b"".join(blobs)
    header = np.array([0x46546C67, 2, len(content) + len(binary) + 28, len(content), 0x4E4F534A], dtype="<u4").tobytes()
    return header + content + np.array([len(binary), 0x004E4942], dtype="<u4").tobytes() + binary


def thick_shell(surface, thickness: float):
    """A closed solid: the limit surface and its offset by ``-thickness`` along the normals.

    The surface's normals point at the body, so the solid grows away from
    it. Boundary loops are closed by side walls; a closed surface gives a
    hollow solid (two nested closed sheets).

    Parameters
    ----------
    surface : seatkit.model.Surface
    thickness : float
        Shell thickness, m (> 0).

    Returns
    -------
    trimesh.Trimesh
        Watertight when the offset does not fold over itself (thickness
        smaller than the surface's radius of curvature).
    """
    import trimesh

    t = float(thickness)
    if not np.isfinite(t) or t <= 0:
        msg = f"shell thickness must be > 0 m, got {thickness!r}"
        raise InputError(msg)
    V = np.asarray(surface.vertices, dtype=np.float64)
    N = np.asarray(surface.normals, dtype=np.float64)
    n = len(V)
    tris = quads_to_triangles(surface.faces)
    top = tris
    bottom = tris[:, ::-1] + n
    # Boundary half-edges: directed edges with no opposite.
    half = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    key = half[:, 0] * n + half[:, 1]
    rkey = half[:, 1] * n + half[:, 0]
    boundary = half[~np.isin(key, rkey)]
    a, b = boundary[:, 0], boundary[:, 1]
    walls = np.concatenate([np.stack([b, a, a + n], axis=1), np.stack([b, a + n, b + n], axis=1)])
    mesh = trimesh.Trimesh(
        vertices=np.concatenate([V, V - t * N]),
        faces=np.concatenate([top, bottom, walls]),
        process=False,
    )
    return mesh


def write_shell(surface, thickness: float, path) -> Path:
    """Write :func:`thick_shell` (format by suffix: .stl .ply .obj .glb)."""
    path = Path(path)
    mesh = thick_shell(surface, thickness)
    with atomic_path(path) as tmp:
        mesh.export(tmp, file_type=path.suffix.lower()[1:])
    return path


#: matplotlib's colour map "magma_r" (magma reversed) as its 256 RGB bytes
#: (:data:`seatkit.picture.colour.MAGMA_R_BYTES`), so that the default colours
#: of :func:`pressure_colors` need no matplotlib import (0.13 s of every
#: build); a test checks it against matplotlib.
_MAGMA_R = MAGMA_R_BYTES


def pressure_colors(pressure: np.ndarray, *, cmap: str = "magma_r") -> np.ndarray:
    """(n, 4) uint8 RGBA colours of pressures, scaled by the maximum.

    Zero pressure maps to the light end of ``cmap`` (a matplotlib colour map
    name), the peak to the dark end; NaN is transparent black, as in
    matplotlib.
    """
    p = np.asarray(pressure, dtype=np.float64)
    peak = float(p.max()) if p.size else 0.0
    importance = np.clip(p / peak, 0.0, 1.0) if peak > 0 else np.zeros_like(p)
    if cmap != "magma_r":
        from matplotlib import colormaps

        return (colormaps[cmap](importance) * 255).round().astype(np.uint8)
    # matplotlib's lookup of a float in [0, 1] in a 256-entry map: the entry
    # int(x * 256), 1.0 being the last
    x = importance * 256.0
    x[x == 256.0] = 255.0
    bad = np.isnan(x)
    index = np.where(bad, 0.0, x).astype(np.int64)
    rgba = np.empty(x.shape + (4,), np.uint8)
    rgba[..., :3] = np.frombuffer(_MAGMA_R, np.uint8).reshape(256, 3)[index]
    rgba[..., 3] = 255
    rgba[bad] = 0
    return rgba


def write_body_ply(body, pressure, path, *, interface=None) -> Path:
    """Write the posed body as a PLY with vertex colours from ``pressure`` (Pa).

    Vertex properties after the colours: ``importance_pa`` (``pressure``:
    the paper's relative importance, Pa) and, with ``interface``, the contact
    on the design from the soft-tissue model: ``force_x``, ``force_y``,
    ``force_z`` (world force on the vertex, N) and ``interface_pa``
    (interface pressure, Pa); zero off the contact.

    Parameters
    ----------
    body : seatkit.model.Body
    pressure : (n,) float64 or seatkit.model.PressureField
    path : str or Path
    interface : seatkit.model.PressureField, optional
    """
    p = np.asarray(getattr(pressure, "pressure", pressure), dtype=np.float64)
    if p.shape != (len(body.vertices),):
        msg = f"pressure must have one value per body vertex ({len(body.vertices)}), got shape {p.shape}"
        raise InputError(msg)
    scalars = {"importance_pa": p}
    if interface is not None:
        force = np.asarray(interface.force, dtype=np.float64)
        scalars.update(force_x=force[:, 0], force_y=force[:, 1], force_z=force[:, 2], interface_pa=interface.pressure)
    return write_bytes_atomic(path, ply_bytes(body.vertices, body.faces, colors=pressure_colors(p), scalars=scalars))
