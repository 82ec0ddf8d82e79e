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
from seatkit.io import jsonable, write_bytes_atomic
from seatkit.model import Body, BuildResult, ControlMesh

FORMAT_VERSION = 1
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
            zf.writestr(info, member.getvalue())
    return write_bytes_atomic(path, buf.getvalue())


def without_timings(value):
    """``value`` without the ``seconds`` entries (wall times differ run to run)."""
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if k != "seconds"}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


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
        When the file is missing or not a seatkit design.
    """
    path = Path(path)
    try:
        data = np.load(path, allow_pickle=False)
        header = json.loads(bytes(data["header"]).decode("utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: no such file; is this a seatkit build folder?") from None
    except (OSError, ValueError, KeyError) as e:
        raise InputError(f"{path}: not a seatkit design file ({e})") from None
    if header.get("format") != FORMAT_VERSION:
        raise InputError(f"{path}: design format {header.get('format')!r}, this seatkit reads {FORMAT_VERSION}")
    bodies = []
    for i, info in enumerate(header["bodies"]):
        kw = {k: data[f"body{i}_{k}"] for k in _BODY_ARRAYS}
        regions = {name: data[f"body{i}_region_{name}"] for name in info["regions"]}
        bodies.append(Body(**kw, name=info["name"], region_labels=regions))

    def mesh(role):
        if role not in header["meshes"]:
            return None
        kw = {k: data[f"{role}_{k}"] for k in _MESH_ARRAYS}
        m = header["meshes"][role]
        return ControlMesh(**kw, face_labels=tuple(m["face_labels"]), meta=m["meta"])

    recipe = header["recipe"]
    lam = recipe.get("pressure", {}).get("lambda")
    if isinstance(lam, str):
        recipe["pressure"]["lambda"] = float(lam)
    return recipe, bodies, mesh("final"), mesh("initial")


class DesignExporter:
    """``design.npz``: recipe, posed bodies and cages, for ``seatkit evaluate``."""

    name = "design"
    description = "design.npz: the recipe, posed bodies and cages (for seatkit evaluate)"

    prepare_ahead = False

    def prepare(self) -> None:
        """Nothing to prepare: this exporter imports nothing big."""

    def export(self, result: BuildResult, directory) -> dict[str, Path]:
        return {"design": save_design(result, Path(directory) / "design.npz")}
