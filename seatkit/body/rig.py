"""Rigged bodies: seatkit ``.npz`` rig files, their validation, and the embedded defaults' paths.

A body by name or path (the parametric defaults, rig files, glTF):
:func:`seatkit.body.loading.load_rig`.

A seatkit rig file is a compressed ``.npz`` holding (float32 storage is fine;
everything is cast to float64 on load):

==================  ==============  ============================================
key                 shape           meaning
==================  ==============  ============================================
``vertices``        (n, 3)          rest-pose vertices, m, +Y up, facing +Z
``faces``           (m, 3) int      triangles, counter-clockwise from outside
``weights``         (n, 21)         skinning weights per segment (rows -> 1)
``joints``          (21, 3)         proximal joint of each segment, m
``tips``            (21, 3)         distal end of each segment, m
``region_<name>``   (k,) int        optional named vertex sets (``face`` ...)
``meta``            () str          optional JSON: provenance; ``sex`` selects
                                    the Plagenhoef column (default ``male``)
==================  ==============  ============================================

The rest pose must have every segment frame aligned with the world axes (a
T-pose: arms along +-X, legs straight down), because pose rotations are given
in those axes (see :mod:`seatkit.body.skinning`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from seatkit.body.anthropometry import com_ratios, segment_masses
from seatkit.constants import BODY_SIZE_RANGE, DEFAULT_BODY_MASS
from seatkit.errors import InputError
from seatkit.messages import quote
from seatkit.model import RiggedBody
from seatkit.resources import data_path
from seatkit.skeleton import N_SEGMENTS

__all__ = ["DEFAULT_BODIES", "default_body_path", "load_rig", "load_rig_file", "make_rig", "save_rig"]

#: Names of the embedded default bodies.
DEFAULT_BODIES: tuple[str, ...] = ("default-male", "default-female")

#: Tolerance on a row of skinning weights summing to 1 in a rig file.
WEIGHT_SUM_TOL = 1e-3


def default_body_path(name: str) -> Path:
    """Path of an embedded default body's ``.npz``."""
    return data_path("bodies", f"{name}.npz")


def check_body_arrays(vertices, faces, weights, joints, tips, *, source: str = "body"):
    """Validated body arrays: what :func:`make_rig` and ``design.npz`` bodies must satisfy.

    Returns ``(vertices, faces, weights, joints, tips)`` as float64 / int64
    arrays, the weights normalised. Raises :class:`InputError` naming
    ``source`` for wrong shapes, NaN or infinities, faces out of range, bad
    weights, a segment owning no vertex, a body not 0.3 to 3 m across, joints
    or tips outside it.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        msg = f"{source}: vertices must be (n, 3), got {vertices.shape}"
        raise InputError(msg)
    n = len(vertices)
    if not np.isfinite(vertices).all():
        bad = np.flatnonzero(~np.isfinite(vertices).all(axis=1))
        msg = f"{source}: {bad.size} vertices are NaN or infinite (first: vertex {bad[0]})"
        raise InputError(msg)
    size = float(np.ptp(vertices, axis=0).max())
    lo, hi = BODY_SIZE_RANGE
    if not lo <= size <= hi:
        msg = f"{source}: the body is {size:.3g} m across; expected a person from {lo:g} to {hi:g} m (vertices are in metres)"
        raise InputError(msg)
    faces_in = np.asarray(faces)
    if faces_in.ndim != 2 or faces_in.shape[1] != 3 or not np.issubdtype(faces_in.dtype, np.integer):
        msg = f"{source}: faces must be (m, 3) integers, got {faces_in.shape} {faces_in.dtype}"
        raise InputError(msg)
    faces = faces_in.astype(np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= n):
        msg = f"{source}: faces index vertices {faces.min()}..{faces.max()}, but there are {n} vertices"
        raise InputError(msg)
    weights = np.asarray(weights, dtype=np.float64)
    if weights.shape != (n, N_SEGMENTS):
        msg = f"{source}: weights must be ({n}, {N_SEGMENTS}), got {weights.shape}"
        raise InputError(msg)
    if not np.isfinite(weights).all() or (weights < 0).any():
        msg = f"{source}: weights must be finite and non-negative"
        raise InputError(msg)
    row_sum = weights.sum(axis=1)
    off = np.abs(row_sum - 1.0) > WEIGHT_SUM_TOL
    if off.any():
        i = int(np.flatnonzero(off)[0])
        msg = f"{source}: weights of {int(off.sum())} vertices do not sum to 1 (vertex {i}: {row_sum[i]:.6g})"
        raise InputError(msg)
    weights = weights / row_sum[:, None]
    touched = (weights > 0).sum(axis=0)
    if (touched == 0).any():
        from seatkit.skeleton import SEGMENTS

        missing = [SEGMENTS[i] for i in np.flatnonzero(touched == 0)]
        msg = f"{source}: segments with no skinned vertex: {', '.join(missing)}"
        raise InputError(msg)
    arrays = {}
    for key, value in (("joints", joints), ("tips", tips)):
        arr = np.asarray(value, dtype=np.float64)
        if arr.shape != (N_SEGMENTS, 3) or not np.isfinite(arr).all():
            msg = f"{source}: {key} must be finite ({N_SEGMENTS}, 3), got {arr.shape}"
            raise InputError(msg)
        # joints lie in the body, tips on it: within its box grown by a quarter of its size
        box_lo, box_hi = vertices.min(axis=0) - size / 4, vertices.max(axis=0) + size / 4
        outside = ~((arr >= box_lo) & (arr <= box_hi)).all(axis=1)
        if outside.any():
            from seatkit.skeleton import SEGMENTS

            k = int(np.flatnonzero(outside)[0])
            msg = f"{source}: {key}[{k}] ({SEGMENTS[k]}) at {np.round(arr[k], 3).tolist()} m lies outside the body"
            raise InputError(msg)
        arrays[key] = arr
    return vertices, faces, weights, arrays["joints"], arrays["tips"]


def make_rig(
    vertices,
    faces,
    weights,
    joints,
    tips,
    *,
    mass: float = DEFAULT_BODY_MASS,
    sex: str = "male",
    name: str = "",
    region_labels: Mapping[str, Any] | None = None,
    meta: Mapping[str, Any] | None = None,
    source: str = "body",
) -> RiggedBody:
    """Validate arrays and make a :class:`RiggedBody` with Plagenhoef masses.

    Parameters
    ----------
    vertices : (n, 3) array_like
        Rest vertices, m.
    faces : (m, 3) array_like of int
    weights : (n, 21) array_like
        Non-negative; each row is normalised to sum to 1 (a row must already
        sum to 1 within 1e-3, or to a positive number if it is float32 data).
    joints, tips : (21, 3) array_like
    mass : float
        Total body mass, kg.
    sex : {"male", "female"}
        Column of the Plagenhoef et al. (1983) table.
    name : str
    region_labels : mapping of str to (k,) int, optional
    meta : mapping, optional
    source : str
        Where the arrays came from (a file name), for error messages.

    Returns
    -------
    RiggedBody

    Raises
    ------
    InputError
        Wrong shapes, NaN or infinite values, faces out of range, negative
        weights, rows of weights that do not sum to 1, a segment owning no
        vertex.
    """
    if not (isinstance(mass, (int, float, np.number)) and math.isfinite(mass) and mass > 0):
        msg = f"{source}: mass: expected a positive number of kg, got {quote(mass)}"
        raise InputError(msg)
    vertices, faces, weights, joints, tips = check_body_arrays(vertices, faces, weights, joints, tips, source=source)
    n = len(vertices)
    regions = {}
    for region, idx in (region_labels or {}).items():
        idx = np.asarray(idx, dtype=np.int64).ravel()
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            msg = f"{source}: region {region!r} indexes vertices outside 0..{n - 1}"
            raise InputError(msg)
        regions[str(region)] = idx
    return RiggedBody(
        vertices=vertices,
        faces=faces,
        weights=weights,
        joints=joints,
        tips=tips,
        mass=float(mass),
        segment_mass=segment_masses(mass, sex),
        com_ratio=com_ratios(sex),
        name=name,
        region_labels=regions,
        meta=dict(meta or {}),
    )


#: Longest ``meta`` text of a rig file, characters, and its deepest nesting.
MAX_META_CHARS = 100_000
MAX_META_DEPTH = 16


def _depth(text: str) -> int:
    """Deepest bracket nesting of JSON text (strings not excluded: an upper bound)."""
    opens = np.frombuffer(text.encode("utf-8", "replace"), dtype=np.uint8)
    step = np.where((opens == ord("[")) | (opens == ord("{")), 1, 0) - np.where((opens == ord("]")) | (opens == ord("}")), 1, 0)
    return int(np.cumsum(step).max(initial=0))


def _rig_meta(value: np.ndarray, path: Path) -> dict:
    """The ``meta`` array of a rig file: one JSON text of a mapping, bounded."""
    if value.dtype.kind not in "US" or value.shape != ():
        msg = f"{path}: meta: expected one JSON text, got an array of {value.dtype} of shape {value.shape}"
        raise InputError(msg)
    text = value.item()
    if isinstance(text, bytes):
        text = text.decode("utf-8", "replace")
    if len(text) > MAX_META_CHARS or _depth(text) > MAX_META_DEPTH:
        msg = f"{path}: meta: expected a small JSON mapping (at most {MAX_META_CHARS:,} characters, {MAX_META_DEPTH} levels deep)"
        raise InputError(msg)
    try:
        meta = json.loads(text)
    except (json.JSONDecodeError, RecursionError, ValueError) as e:
        msg = f"{path}: meta is not JSON ({e})"
        raise InputError(msg) from None
    if not isinstance(meta, dict):
        msg = f"{path}: meta: expected a JSON mapping, got {type(meta).__name__}"
        raise InputError(msg)
    return meta


def load_rig_file(path, *, mass: float = DEFAULT_BODY_MASS, name: str | None = None) -> RiggedBody:
    """Load a seatkit ``.npz`` rig file.

    Parameters
    ----------
    path : str or Path
    mass : float
        Total body mass, kg.
    name : str, optional
        Name of the rig; default the file path.

    Returns
    -------
    RiggedBody

    Raises
    ------
    InputError
        Unreadable file, missing keys, invalid arrays (see :func:`make_rig`).
    """
    from seatkit.io import load_npz

    path = Path(path)
    contents = load_npz(path, "body file")  # a regular file, capped, plain arrays only
    missing = [k for k in ("vertices", "faces", "weights", "joints", "tips") if k not in contents]
    if missing:
        msg = f"{path}: missing arrays {', '.join(missing)} (a seatkit rig needs vertices, faces, weights, joints, tips)"
        raise InputError(msg)
    for key, value in contents.items():
        kinds = "iu" if key == "faces" or key.startswith("region_") else ("US" if key == "meta" else "biuf")
        if value.dtype.kind not in kinds:
            expected = {"iu": "integers", "US": "one JSON text"}.get(kinds, "numbers")
            msg = f"{path}: {quote(key)}: expected {expected}, got an array of {value.dtype}"
            raise InputError(msg)
    meta: dict = {}
    if "meta" in contents:
        meta = _rig_meta(contents["meta"], path)
    regions = {key[len("region_"):]: contents[key] for key in contents if key.startswith("region_")}
    sex = meta.get("sex", "male")
    if sex not in ("male", "female"):
        msg = f"{path}: meta.sex must be 'male' or 'female', got {quote(sex)}"
        raise InputError(msg)
    return make_rig(
        contents["vertices"],
        contents["faces"],
        contents["weights"],
        contents["joints"],
        contents["tips"],
        mass=mass,
        sex=sex,
        name=name if name is not None else str(path),
        region_labels=regions,
        meta=meta,
        source=str(path),
    )


def save_rig(rig: RiggedBody, path, *, sex: str | None = None) -> Path:
    """Write ``rig`` as a seatkit ``.npz`` rig file (float32, compressed).

    Parameters
    ----------
    rig : RiggedBody
    path : str or Path
    sex : str, optional
        Stored in ``meta``; default ``rig.meta['sex']`` or ``male``.

    Returns
    -------
    Path
    """
    from seatkit.io import atomic_write

    path = Path(path)
    meta = dict(rig.meta)
    meta["sex"] = sex or meta.get("sex", "male")
    arrays = {
        "vertices": rig.vertices.astype(np.float32),
        "faces": rig.faces.astype(np.int32),
        "weights": rig.weights.astype(np.float32),
        "joints": rig.joints.astype(np.float32),
        "tips": rig.tips.astype(np.float32),
        "meta": np.array(json.dumps(meta, sort_keys=True, default=str)),
    }
    for region, idx in rig.region_labels.items():
        arrays[f"region_{region}"] = np.asarray(idx, dtype=np.int32)
    with atomic_write(path, "wb") as f:
        np.savez_compressed(f, **arrays)
    return path
