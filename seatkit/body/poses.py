"""Pose YAML files, the pose library, and resolving a POSE argument.

A pose file (documented in ``docs/poses.md``)::

    description: Sitting upright on a chair, feet flat on the floor.
    supported: true            # can the paper's method support it (library metadata)
    base: upright-sitting      # optional: start from another pose
    joints:                    # any subset of the 21 segments, degrees
      RightUpLeg: {x: -90}     # intrinsic XYZ Euler angles, missing axes are 0
      RightLeg: {x: 90, y: 0, z: 0}
    root:
      rotation: {x: -10}
      translation: [0.0, 0.0, 0.0]   # metres

Angles are intrinsic X-Y-Z Euler angles in degrees
(``scipy.spatial.transform.Rotation.from_euler("XYZ", [x, y, z],
degrees=True)``): rotate about the segment's X axis, then about the new Y,
then about the newer Z. Axes are the world axes of the rest pose (+X the
body's left, +Y up, +Z forwards), the rotation is relative to the parent
segment and about the segment's proximal joint (see
:mod:`seatkit.body.skinning`). A joint listed in a file replaces that joint
of its ``base`` as a whole; joints not listed keep the base's angles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from seatkit.errors import InputError, PluginError, RecipeError
from seatkit.model import Pose
from seatkit.resources import data_path
from seatkit.skeleton import N_SEGMENTS, SEGMENT_INDEX, SEGMENTS
from seatkit.messages import clip, quote
from seatkit.io import MAX_FILE_BYTES, check_user_file
from seatkit.yamlio import check_collection_tag, compose_yaml, read_text, scalar_value

__all__ = [
    "EULER_ORDER",
    "PoseInfo",
    "PoseSpec",
    "builtin_pose_dir",
    "euler_to_rotvec",
    "list_poses",
    "pose_names",
    "load_pose",
    "load_pose_file",
    "pose_dirs",
    "find_pose",
]

#: Euler convention of pose files: intrinsic X, then Y, then Z (scipy's "XYZ").
EULER_ORDER = "XYZ"

TOP_KEYS = ("description", "supported", "base", "joints", "root")
ROOT_KEYS = ("rotation", "translation")
AXES = ("x", "y", "z")
#: Largest joint angle a pose file may give, degrees (two full turns).
MAX_ANGLE_DEG = 720.0
#: Largest root translation a pose file may give, m: a body far from the
#: origin loses its shape in float64 rounding (1e17 m collapses it).
MAX_TRANSLATION = 100.0
POSE_SUFFIXES = (".yaml", ".yml")


@dataclass(frozen=True)
class PoseInfo:
    """One pose of the library, as ``seatkit poses`` lists it."""

    name: str
    description: str
    supported: bool
    path: Path


@dataclass(frozen=True)
class PoseSpec:
    """A pose file resolved against its bases, still in degrees.

    Attributes
    ----------
    angles : (21, 3) float64
        Intrinsic XYZ Euler angles per segment, degrees.
    root_translation : (3,) float64
        m.
    description : str
    supported : bool
    path : Path
    """

    angles: np.ndarray
    root_translation: np.ndarray
    description: str
    supported: bool
    path: Path

    def to_pose(self, name: str = "") -> Pose:
        """The :class:`Pose` (rotation vectors in radians)."""
        return Pose(euler_to_rotvec(self.angles), self.root_translation, name or self.path.stem)


def euler_to_rotvec(angles_deg) -> np.ndarray:
    """Pose-file angles to rotation vectors.

    Parameters
    ----------
    angles_deg : (k, 3) array_like
        Intrinsic XYZ Euler angles, degrees.

    Returns
    -------
    rotvec : (k, 3) float64
        Rotation vectors, radians.
    """
    return Rotation.from_euler(EULER_ORDER, np.asarray(angles_deg, dtype=np.float64), degrees=True).as_rotvec()


# --------------------------------------------------------------------------- library


def builtin_pose_dir() -> Path:
    """The folder of the shipped pose library."""
    return data_path("poses")


def pose_dirs(dirs=None) -> list[tuple[Path, str]]:
    """Folders of pose YAML files, with the plugin that registered each.

    Parameters
    ----------
    dirs : sequence of (Path, str), optional
        The folders a registry collected from
        :func:`seatkit.hookspecs.seatkit_register_pose_dirs`
        (``registry.pose_dirs``); default: the shipped library alone (what
        the built-in ``bodies`` plugin registers).

    Returns
    -------
    list of (Path, str)
        (folder, plugin name), in registration order, without duplicates.
    """
    found = [(builtin_pose_dir().resolve(), "bodies")] if dirs is None else [(Path(d).resolve(), p) for d, p in dirs]
    unique: list[tuple[Path, str]] = []
    for d, plugin in found:
        if d not in {u for u, _ in unique}:
            unique.append((d, plugin))
    return unique


def _library(dirs=None) -> dict[str, tuple[Path, str]]:
    """Pose name -> (file, plugin); a name defined twice is an error."""
    poses: dict[str, tuple[Path, str]] = {}
    for folder, plugin in pose_dirs(dirs):
        if not folder.is_dir():
            continue
        for path in sorted(p for p in folder.iterdir() if p.suffix in POSE_SUFFIXES):
            name = path.stem
            if name in poses:
                other_path, other_plugin = poses[name]
                msg = (
                    f"pose {name!r} is defined twice: {other_path} (plugin \"{other_plugin}\") "
                    f"and {path} (plugin \"{plugin}\")"
                )
                raise PluginError(msg)
            poses[name] = (path, plugin)
    return poses


def find_pose(name: str, dirs=None) -> Path:
    """Path of a library pose by name (``dirs``: see :func:`pose_dirs`).

    Raises
    ------
    RecipeError
        Unknown name, listing the library.
    """
    library = _library(dirs)
    try:
        return library[name][0]
    except KeyError:
        msg = f"unknown pose {name!r}: not a file and not in the pose library ({', '.join(sorted(library))})"
        raise RecipeError(msg) from None


def pose_names(dirs=None) -> list[str]:
    """Every library pose's name, sorted, from the file names alone (``dirs``: see :func:`pose_dirs`).

    Raises
    ------
    PluginError
        A name defined twice.
    """
    return sorted(_library(dirs))


def list_poses(dirs=None) -> list[PoseInfo]:
    """Every library pose with its description and whether it is supported (``dirs``: see :func:`pose_dirs`).

    Returns
    -------
    list of PoseInfo
        Sorted by name.
    """
    infos = []
    for name, (path, _) in sorted(_library(dirs).items()):
        node = _compose(path)
        top = _mapping_items(node, path, "")
        description = ""
        supported = True
        if "description" in top:
            description = str(_scalar(top["description"][1], path))
        if "supported" in top:
            supported = _bool(top["supported"][1], path, "supported")
        infos.append(PoseInfo(name, description.strip(), supported, path))
    return infos


# --------------------------------------------------------------------------- YAML


def _where(path: Path, node: yaml.Node) -> str:
    return f"{path}:{node.start_mark.line + 1}"


def _compose(path: Path) -> yaml.Node:
    if not path.exists():
        msg = f"{path}: no such pose file"
        raise InputError(msg)
    # UTF-8 only, bounded size, depth and alias expansion (seatkit.yamlio)
    node = compose_yaml(read_text(path, "pose file"), source=str(path))
    if node is None:
        msg = f"{path}:1: empty pose file; expected a mapping with keys {', '.join(TOP_KEYS)}"
        raise RecipeError(msg)
    return node


def _scalar(node: yaml.Node, path: Path | str = "<pose>") -> Any:
    return scalar_value(node, str(path))


def _mapping_items(node: yaml.Node, path: Path, key_path: str) -> dict[str, tuple[yaml.Node, yaml.Node]]:
    """Keys of a mapping node -> (key node, value node)."""
    if not isinstance(node, yaml.MappingNode):
        where = key_path or "the file"
        msg = f"{_where(path, node)}: {where}: expected a mapping, got {_kind(node)}"
        raise RecipeError(msg)
    check_collection_tag(node, str(path))
    items: dict[str, tuple[yaml.Node, yaml.Node]] = {}
    for k, v in node.value:
        if not isinstance(k, yaml.ScalarNode):
            msg = f"{_where(path, k)}: {key_path or 'the file'}: keys must be plain names, got {_kind(k)}"
            raise RecipeError(msg)
        key = clip(str(_scalar(k, path)), 80)
        if key in items:
            msg = f"{_where(path, k)}: {_join(key_path, key)}: key given twice"
            raise RecipeError(msg)
        items[key] = (k, v)
    return items


def _kind(node: yaml.Node) -> str:
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    return quote(node.value)


def _join(key_path: str, key: str) -> str:
    return f"{key_path}.{key}" if key_path else key


def _number(node: yaml.Node, path: Path, key_path: str, what: str, limit: float) -> float:
    """A finite number with ``abs(value) <= limit``."""
    value = _scalar(node, path) if isinstance(node, yaml.ScalarNode) else None
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and abs(value) < 1e300
    if not ok or not math.isfinite(value) or abs(value) > limit:
        msg = f"{_where(path, node)}: {key_path}: expected {what} from {-limit:g} to {limit:g}, got {_kind(node)}"
        raise RecipeError(msg)
    return float(value)


def _bool(node: yaml.Node, path: Path, key_path: str) -> bool:
    value = _scalar(node, path) if isinstance(node, yaml.ScalarNode) else None
    if not isinstance(value, bool):
        msg = f"{_where(path, node)}: {key_path}: expected true or false, got {_kind(node)}"
        raise RecipeError(msg)
    return value


def _angles(node: yaml.Node, path: Path, key_path: str) -> np.ndarray:
    items = _mapping_items(node, path, key_path)
    angles = np.zeros(3)
    for key, (knode, vnode) in items.items():
        if key not in AXES:
            msg = f"{_where(path, knode)}: {_join(key_path, key)}: unknown axis; expected x, y, z (degrees)"
            raise RecipeError(msg)
        angles[AXES.index(key)] = _number(vnode, path, _join(key_path, key), "an angle in degrees", MAX_ANGLE_DEG)
    return angles


def _resolve_base(base: str, path: Path, node: yaml.Node, roots=None) -> Path:
    if base.endswith(POSE_SUFFIXES):
        try:
            candidate = (path.parent / base).resolve()
            if roots is not None and not any(candidate.is_relative_to(Path(r).resolve()) for r in roots):
                # refused before the file is opened: nothing of it (not even whether it exists) is told
                msg = f"{_where(path, node)}: base: {quote(base)} is outside the folders base poses are read from here"
                raise RecipeError(msg)
            found = candidate.is_file()
        except (OSError, ValueError):  # a name too long for the file system, a NUL byte
            found = False
        if not found:
            msg = f"{_where(path, node)}: base: no pose file {quote(base)} beside {path.name}"
            raise RecipeError(msg)
        return candidate
    library = _library()
    if base not in library:
        msg = f"{_where(path, node)}: base: unknown pose {quote(base)}; expected one of {', '.join(sorted(library))}"
        raise RecipeError(msg)
    return library[base][0]


#: Most pose files a chain of ``base:`` keys may pass through.
MAX_BASE_DEPTH = 16


def load_pose_file(path, *, base_roots=None, _chain: tuple[Path, ...] = ()) -> PoseSpec:
    """Read and validate a pose YAML file, resolving its ``base`` chain.

    Parameters
    ----------
    path : str or Path
    base_roots : sequence of Path, optional
        The folders a ``base:`` file may be in (``seatkit serve``: the pose
        library, the plugins' pose folders, its uploads); a base file
        elsewhere is refused before it is opened. Default: anywhere.

    Returns
    -------
    PoseSpec

    Raises
    ------
    RecipeError
        With the file, line, key path and what was expected: an unknown key,
        joint or axis, an angle that is not a number, an unknown base, a
        cycle of bases.
    InputError
        The file cannot be read.
    """
    given = Path(path)
    if given.exists():  # a FIFO or a symlink to a device is named as the user gave it, before resolving
        check_user_file(given, "pose file", max_bytes=MAX_FILE_BYTES["YAML"], error=RecipeError)
    path = given.resolve()
    node = _compose(path)
    top = _mapping_items(node, path, "")
    for key, (knode, _) in top.items():
        if key not in TOP_KEYS:
            msg = f"{_where(path, knode)}: {key}: unknown key; expected one of {', '.join(TOP_KEYS)}"
            raise RecipeError(msg)

    description = ""
    if "description" in top:
        value = top["description"][1]
        if not isinstance(value, yaml.ScalarNode):
            msg = f"{_where(path, value)}: description: expected text, got {_kind(value)}"
            raise RecipeError(msg)
        description = str(_scalar(value, path)).strip()
    supported = _bool(top["supported"][1], path, "supported") if "supported" in top else True

    angles = np.zeros((N_SEGMENTS, 3))
    translation = np.zeros(3)
    if "base" in top:
        bnode = top["base"][1]
        base_name = _scalar(bnode, path) if isinstance(bnode, yaml.ScalarNode) else None
        if not isinstance(base_name, str) or not base_name:
            msg = f"{_where(path, bnode)}: base: expected a pose name or a pose file path, got {_kind(bnode)}"
            raise RecipeError(msg)
        base_path = _resolve_base(base_name, path, bnode, base_roots)
        chain = _chain + (path,)
        if base_path in chain:
            cycle = " -> ".join(p.stem for p in chain[chain.index(base_path):] + (base_path,))
            msg = f"{_where(path, bnode)}: base: cycle of base poses ({clip(cycle, 200)})"
            raise RecipeError(msg)
        if len(chain) >= MAX_BASE_DEPTH:
            msg = (
                f"{_where(path, bnode)}: base: a chain of more than {MAX_BASE_DEPTH} pose files "
                f"({chain[0].name} -> ... -> {path.name} -> {base_path.name}); seatkit follows at most {MAX_BASE_DEPTH}"
            )
            raise RecipeError(msg)
        base = load_pose_file(base_path, base_roots=base_roots, _chain=chain)
        angles = base.angles.copy()
        translation = base.root_translation.copy()

    if "joints" in top:
        jnode = top["joints"][1]
        if not (isinstance(jnode, yaml.ScalarNode) and _scalar(jnode, path) is None):
            for joint, (knode, vnode) in _mapping_items(jnode, path, "joints").items():
                if joint not in SEGMENT_INDEX:
                    msg = f"{_where(path, knode)}: joints.{joint}: unknown joint; expected one of {', '.join(SEGMENTS)}"
                    raise RecipeError(msg)
                if joint == SEGMENTS[0]:
                    msg = f"{_where(path, knode)}: joints.{joint}: the root segment is posed under root.rotation"
                    raise RecipeError(msg)
                angles[SEGMENT_INDEX[joint]] = _angles(vnode, path, f"joints.{joint}")

    if "root" in top:
        root = _mapping_items(top["root"][1], path, "root")
        for key, (knode, vnode) in root.items():
            if key not in ROOT_KEYS:
                msg = f"{_where(path, knode)}: root.{key}: unknown key; expected one of {', '.join(ROOT_KEYS)}"
                raise RecipeError(msg)
        if "rotation" in root:
            angles[0] = _angles(root["rotation"][1], path, "root.rotation")
        if "translation" in root:
            tnode = root["translation"][1]
            if not isinstance(tnode, yaml.SequenceNode) or len(tnode.value) != 3:
                msg = f"{_where(path, tnode)}: root.translation: expected [x, y, z] in metres, got {_kind(tnode)}"
                raise RecipeError(msg)
            translation = np.array(
                [
                    _number(v, path, f"root.translation[{i}]", "a number of metres", MAX_TRANSLATION)
                    for i, v in enumerate(tnode.value)
                ]
            )
    return PoseSpec(angles, translation, description, supported, path)


def load_pose(pose, *, frame: int | None = None, rig=None, dirs=None) -> Pose:
    """Resolve a POSE argument into a :class:`Pose`.

    Parameters
    ----------
    pose : Pose, str or Path
        A :class:`Pose` (returned as is), a path to a pose YAML file, a path
        to a ``.bvh`` file, or the name of a library pose.
    frame : int, optional
        BVH frame (default: the BVH loader's default).
    rig : RiggedBody, optional
        Body the BVH motion is retargeted onto.
    dirs : sequence of (Path, str), optional
        Pose folders of a registry (``registry.pose_dirs``) a library name
        is looked up in; default the shipped library (see :func:`pose_dirs`).

    Returns
    -------
    Pose

    Raises
    ------
    RecipeError
        Unknown pose name or a malformed pose file.
    InputError
        An unreadable file.
    """
    if isinstance(pose, Pose):
        return pose
    spec = str(pose)
    path = Path(spec)
    if path.suffix.lower() == ".bvh":
        from seatkit.body.bvh import load_bvh

        kwargs: dict[str, Any] = {"rig": rig}
        if frame is not None:
            kwargs["frame"] = frame
        return load_bvh(path, **kwargs)
    if path.suffix.lower() in POSE_SUFFIXES or path.is_file():
        return load_pose_file(path).to_pose(name=path.stem)
    return load_pose_file(find_pose(spec, dirs)).to_pose(name=spec)
