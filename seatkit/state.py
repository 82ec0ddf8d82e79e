"""The machine-readable state of a build: ``design.npz``.

It holds what is needed to re-evaluate or re-export a design later without
re-running the template: the recipe, every posed body (vertices, faces,
skinning weights, joints, masses) and the final and initial control meshes.
``seatkit evaluate DIR`` reads it. Keys are documented in docs/output.md.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import fields
from pathlib import Path

import numpy as np

from seatkit.errors import InputError
from seatkit.messages import clip, quote
from seatkit.io import jsonable, write_bytes_atomic
from seatkit.model import Body, BuildResult, ControlMesh

FORMAT_VERSION = 1
#: zlib level of ``design.npz``'s members: 1 writes the default design in
#: half the time of zlib's default (6), for a file about 6% larger; any
#: level reads the same (docs/performance.md, "One build as a whole process").
DESIGN_ZLIB_LEVEL = 1
_BODY_ARRAYS = ("vertices", "faces", "weights", "joints", "tips", "segment_mass", "segment_com")
_MESH_ARRAYS = tuple(
    f.name for f in fields(ControlMesh) if f.name not in ("meta", "face_labels")
)


def save_design(result: BuildResult, path) -> Path:
    """Write ``design.npz`` for a build result (atomically)."""
    arrays: dict[str, np.ndarray] = {}
    header = {
        "format": FORMAT_VERSION,
        "recipe": jsonable(result.recipe),
        "bodies": [],
        "meshes": {},
    }
    for i, body in enumerate(result.bodies):
        for key in _BODY_ARRAYS:
            arrays[f"body{i}_{key}"] = np.asarray(getattr(body, key))
        for name, idx in body.region_labels.items():
            arrays[f"body{i}_region_{name}"] = np.asarray(idx, dtype=np.int64)
        header["bodies"].append({"name": body.name, "regions": sorted(body.region_labels)})
    for role, mesh in (("final", result.control_mesh), ("initial", result.initial_mesh)):
        if mesh is None:
            continue
        for key in _MESH_ARRAYS:
            arrays[f"{role}_{key}"] = np.asarray(getattr(mesh, key))
        header["meshes"][role] = {"face_labels": list(mesh.face_labels), "meta": jsonable(mesh.meta)}
    arrays["header"] = np.frombuffer(json.dumps(without_timings(header), sort_keys=True).encode("utf-8"), dtype=np.uint8)
    # byte-identical for the same inputs and seed: fixed zip timestamps, no timings
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in sorted(arrays):
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asarray(arrays[name]), allow_pickle=False)
            zf.writestr(info, member.getvalue(), compresslevel=DESIGN_ZLIB_LEVEL)
    return write_bytes_atomic(path, buf.getvalue())


def without_timings(value):
    """``value`` without the ``seconds`` entries (wall times differ run to run)."""
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if k != "seconds"}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


#: Most people a design holds (a template seats at most 64).
MAX_DESIGN_BODIES = 64
#: Largest JSON header of a design, bytes.
MAX_HEADER_BYTES = 16 * 1024 * 1024


def _header(arrays: dict, path: Path) -> dict:
    """The JSON header of a design, its shape checked."""
    raw = arrays.get("header")
    if raw is None or raw.dtype != np.uint8 or raw.ndim != 1 or raw.size > MAX_HEADER_BYTES:
        raise InputError(f"{path}: not a seatkit design file (no header: expected a 1-D uint8 array of JSON)")
    try:
        header = json.loads(raw.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise InputError(f"{path}: header: not JSON text ({e})") from None
    if not isinstance(header, dict):
        raise InputError(f"{path}: header: expected a JSON mapping, got {type(header).__name__}")
    if header.get("format") != FORMAT_VERSION:
        raise InputError(f"{path}: design format {quote(header.get('format'))}, this seatkit reads {FORMAT_VERSION}")
    bodies, meshes = header.get("bodies"), header.get("meshes")
    if not isinstance(bodies, list) or not 1 <= len(bodies) <= MAX_DESIGN_BODIES or not all(
        isinstance(b, dict) and isinstance(b.get("name"), str) and isinstance(b.get("regions"), list)
        and all(isinstance(r, str) for r in b["regions"]) for b in bodies
    ):
        msg = f"{path}: header.bodies: expected 1 to {MAX_DESIGN_BODIES} mappings with a name and a list of regions"
        raise InputError(msg)
    if not isinstance(meshes, dict) or "final" not in meshes or not set(meshes) <= {"final", "initial"} or not all(
        isinstance(m, dict) and isinstance(m.get("face_labels"), list) and isinstance(m.get("meta"), dict)
        and all(isinstance(t, str) for t in m["face_labels"]) for m in meshes.values()
    ):
        msg = f"{path}: header.meshes: expected 'final' (and 'initial') mappings with face_labels and meta"
        raise InputError(msg)
    if not isinstance(header.get("recipe"), dict):
        raise InputError(f"{path}: header.recipe: expected a mapping")
    return header


def _array(arrays: dict, key: str, path: Path, kinds: str, shape: tuple) -> np.ndarray:
    """``arrays[key]`` of one of the dtype ``kinds`` and ``shape`` (None: any length)."""
    a = arrays.get(key)
    if a is None:
        raise InputError(f"{path}: missing array {quote(key)}")
    ok = a.dtype.kind in kinds and a.ndim == len(shape) and all(w is None or w == n for w, n in zip(shape, a.shape))
    if not ok:
        want = "x".join("n" if w is None else str(w) for w in shape) or "a scalar"
        raise InputError(f"{path}: {key}: expected a ({want}) array of {'integers' if kinds == 'iu' else 'numbers'}, got {a.dtype} {a.shape}")
    if a.dtype.kind == "f" and key.rsplit("_", 1)[-1] not in ("points", "normals") and not np.isfinite(a).all():
        raise InputError(f"{path}: {key}: expected finite numbers")
    return a


def _design_body(arrays: dict, i: int, info: dict, path: Path) -> Body:
    from seatkit.body.rig import check_body_arrays
    from seatkit.skeleton import N_SEGMENTS

    key = f"body{i}_"
    vertices, faces, weights, joints, tips = check_body_arrays(
        *(_array(arrays, key + k, path, "iu" if k == "faces" else "biuf", s)
          for k, s in (("vertices", (None, 3)), ("faces", (None, 3)), ("weights", (None, N_SEGMENTS)), ("joints", (N_SEGMENTS, 3)), ("tips", (N_SEGMENTS, 3)))),
        source=f"{path}: body {i}",
    )
    mass = _array(arrays, key + "segment_mass", path, "biuf", (N_SEGMENTS,)).astype(np.float64)
    if (mass < 0).any() or not 1.0 <= mass.sum() <= 1000.0:
        raise InputError(f"{path}: {key}segment_mass: expected non-negative segment masses summing to 1 to 1000 kg")
    com = _array(arrays, key + "segment_com", path, "biuf", (N_SEGMENTS, 3)).astype(np.float64)
    size = float(np.ptp(vertices, axis=0).max())
    if not ((com >= vertices.min(axis=0) - size / 4) & (com <= vertices.max(axis=0) + size / 4)).all():
        raise InputError(f"{path}: {key}segment_com: centres of mass outside the body")
    regions = {}
    for name in info["regions"]:
        idx = _array(arrays, f"{key}region_{name}", path, "iu", (None,)).astype(np.int64)
        if idx.size and (idx.min() < 0 or idx.max() >= len(vertices)):
            raise InputError(f"{path}: {key}region_{clip(name)}: vertex indices outside 0..{len(vertices) - 1}")
        regions[name] = idx
    return Body(vertices, faces, weights, joints, tips, mass, com, name=info["name"], region_labels=regions)


def _design_mesh(arrays: dict, role: str, info: dict, path: Path, n_people: int) -> ControlMesh:
    from seatkit.export.meshes import MAX_CAGE_COORDINATE
    from seatkit.skeleton import N_SEGMENTS
    from seatkit.subdivision import Cage

    vertices = _array(arrays, f"{role}_vertices", path, "biuf", (None, 3)).astype(np.float64)
    nv = len(vertices)
    faces = _array(arrays, f"{role}_faces", path, "iu", (None, 4)).astype(np.int64)
    nf = len(faces)
    if nf == 0 or (np.abs(vertices) > MAX_CAGE_COORDINATE).any():
        raise InputError(f"{path}: {role}_vertices: expected a cage with faces, within +-{MAX_CAGE_COORDINATE:g} m")
    shapes = {
        "face_segments": ("iu", (nf,)), "face_person": ("iu", (nf,)), "plane_points": ("f", (nf, 3)),
        "plane_normals": ("f", (nf, 3)), "vertex_weights": ("biuf", (nv,)), "fixed": ("b", (nv,)),
        "ground": ("b", (nv,)), "crease_edges": ("iu", (None, 2)), "crease_sharpness": ("biuf", (None,)),
        "corners": ("iu", (None,)), "corner_sharpness": ("biuf", (None,)),
    }
    kw = {k: _array(arrays, f"{role}_{k}", path, kinds, shape) for k, (kinds, shape) in shapes.items()}
    if ((kw["face_segments"] < -1) | (kw["face_segments"] >= N_SEGMENTS)).any():
        raise InputError(f"{path}: {role}_face_segments: expected segment numbers from -1 to {N_SEGMENTS - 1}")
    if ((kw["face_person"] < -1) | (kw["face_person"] >= n_people)).any():
        raise InputError(f"{path}: {role}_face_person: expected person numbers from -1 to {n_people - 1}")
    if (kw["vertex_weights"] < 0).any():
        raise InputError(f"{path}: {role}_vertex_weights: expected non-negative weights")
    if len(info["face_labels"]) not in (0, nf):
        raise InputError(f"{path}: header.meshes.{role}.face_labels: expected {nf} labels, got {len(info['face_labels'])}")
    mesh = ControlMesh(vertices, faces, **kw, face_labels=tuple(info["face_labels"]), meta=info["meta"])
    try:
        Cage.from_control_mesh(mesh)  # the topology, creases and corners, as evaluate will refine them
    except InputError as e:
        raise InputError(f"{path}: {role} cage: {e}") from None
    return mesh


def load_design(path) -> tuple[dict, list[Body], ControlMesh, ControlMesh | None]:
    """Read ``design.npz``.

    Returns
    -------
    recipe : dict
    bodies : list of Body
    mesh : ControlMesh
        The final cage.
    initial : ControlMesh or None
        The template's cage before refiners.

    Raises
    ------
    InputError
        When the file is missing or not a seatkit design: every array is
        checked (shapes, types, finite values, indices in range, bodies of
        0.3 to 3 m with their joints in them, cages Catmull-Clark can
        refine) before any work. The recipe is a mapping: ``seatkit
        evaluate`` checks it (:func:`seatkit.designs.load_checked_design`).
    """
    from seatkit.io import load_npz

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file; is this a seatkit build folder?")
    arrays = load_npz(path, "design file")
    header = _header(arrays, path)
    recipe = header["recipe"]
    pressure = recipe.get("pressure")
    if isinstance(pressure, dict) and isinstance(pressure.get("lambda"), str):
        try:
            pressure["lambda"] = float(pressure["lambda"])  # JSON has no inf: written as "inf"
        except ValueError:
            raise InputError(f"{path}: header.recipe.pressure.lambda: expected a number, got {quote(pressure['lambda'])}") from None
    bodies = [_design_body(arrays, i, info, path) for i, info in enumerate(header["bodies"])]
    meshes = {
        role: _design_mesh(arrays, role, info, path, len(bodies)) for role, info in header["meshes"].items()
    }
    return recipe, bodies, meshes["final"], meshes.get("initial")


class DesignExporter:
    """``design.npz``: recipe, posed bodies and cages, for ``seatkit evaluate``."""

    name = "design"
    description = "design.npz: the recipe, posed bodies and cages (for seatkit evaluate)"

    prepare_ahead = False
    design_only = True

    def prepare(self) -> None:
        """Nothing to prepare: this exporter imports nothing big."""

    def export(self, result: BuildResult, directory) -> dict[str, Path]:
        return {"design": save_design(result, Path(directory) / "design.npz")}
