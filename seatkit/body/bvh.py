"""BVH motion files: read a frame as a seatkit :class:`~seatkit.model.Pose`, write poses.

Reading
-------
:func:`read_bvh` parses HIERARCHY and MOTION (any channel order, Euler
rotation channels in degrees, position channels on the root) into a
:class:`BvhMotion`. :func:`load_bvh` turns one frame into a Pose for a rig:

1. **Names.** A name map (YAML, ``seatkit/data/name_maps/``) lists for each of
   the 21 segments the BVH joint names that drive it. The built-in
   Perception Neuron, CMU and Mixamo maps are tried and the one that
   recognises most joint names of the file wins (each map also lists the
   extra joints of its convention: fingers, toes, end joints). Names match
   case-insensitively after dropping a namespace prefix (``mixamorig:``). A
   user map (a YAML path or a dict) is laid over every built-in one: its
   names come first for the segments it lists (``base: cmu`` picks the
   built-in map it extends; ``base: none`` uses it alone).
2. **Axes.** The BVH rest skeleton (every channel zero) gives the body's up
   direction (hips to head) and left direction (right hip to left hip); the
   nearest axis-aligned rotation ``A`` that takes them to seatkit's +Y up
   and +X left (so the body faces +Z) converts the file's axes. A file that
   is already +Y up, facing +Z, gets ``A = I``.
3. **Rotations only.** Each BVH joint's world orientation ``Q_j`` (product
   of the local Euler rotations down the chain) is taken; offsets are used
   only for directions, so the rig keeps its own proportions. A segment's
   world rotation is ``G_s = S_s @ A Q_j A^T @ C_s`` where

   - ``C_s`` corrects the rest pose: the smallest rotation that turns the
     rig's rest bone (segment joint to the joint of its next mapped
     descendant, e.g. shoulder to elbow) onto the BVH's rest bone. A T-pose
     file on an A-pose rig thus gets its arms right. The end segments (Head,
     Hands, Feet) take their parent's correction (their rest angle to the
     parent is assumed the same in both skeletons); the root takes none (the
     axis conversion ``A`` already aligns it).
   - ``S_s`` is the smallest rotation that turns the bone onto the BVH's
     posed chord from the joint to the next mapped descendant joint; it is
     the identity unless unmapped joints lie between them, and then it
     folds their bending into the mapped segment (e.g. CMU ``Neck1`` into
     ``Neck``). The twist about the bone stays that of the mapped joint.
   - A segment with no joint in the file (Spine2 for CMU and Mixamo) keeps
     its parent's orientation (zero relative rotation).

   Joints below the end segments (fingers, toes, head-top and end sites)
   are ignored. Position channels of non-root joints are ignored.
4. **Root motion** (optional, ``root_motion=True``): the translation is the
   root's position in this frame minus its position in frame 0, converted
   to metres and to seatkit axes. Otherwise it is zero.

Units: BVH records none. The rest skeleton's height (joints and end sites,
along its up axis) is compared with a human's (about 1.5 m between the feet
and the head-top end site); the unit among m, cm, mm and inch that makes it
closest (in ratio) is taken, unless ``unit=`` is given. Only root motion
depends on it.

Writing
-------
:func:`write_bvh` writes poses of a rig as a BVH in centimetres with +Y up,
the body facing +Z, the rig's rest pose as the BVH rest pose and the naming
of a name map, so that :func:`load_bvh` on the same rig gives the same poses
back.
"""

from __future__ import annotations

import functools

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from seatkit.errors import InputError, RecipeError
from seatkit.messages import clip, quote
from seatkit.yamlio import decode_text
from seatkit.model import Pose, RiggedBody
from seatkit.resources import data_path
from seatkit.skeleton import N_SEGMENTS, PARENTS, SEGMENTS, SEGMENT_INDEX

__all__ = [
    "BUILTIN_BVH_MAPS",
    "REQUIRED_SEGMENTS",
    "BvhMotion",
    "NameMap",
    "load_name_map",
    "read_bvh",
    "load_bvh",
    "write_bvh",
]

#: Built-in BVH name maps, in the order they are tried.
BUILTIN_BVH_MAPS: tuple[str, ...] = ("perception-neuron", "cmu", "mixamo")

#: Segments a BVH (or glTF skin) must provide; the others (Spine..Spine3,
#: Neck, Shoulders) may be missing and then follow their parent.
REQUIRED_SEGMENTS: tuple[str, ...] = (
    "Hips",
    "RightUpLeg",
    "RightLeg",
    "RightFoot",
    "LeftUpLeg",
    "LeftLeg",
    "LeftFoot",
    "Head",
    "RightArm",
    "RightForeArm",
    "RightHand",
    "LeftArm",
    "LeftForeArm",
    "LeftHand",
)

#: The child along the main chain of each segment (-1 for end segments).
CHAIN_CHILD: np.ndarray = np.array(
    [7, 2, 3, -1, 5, 6, -1, 8, 9, 10, 11, 12, -1, 14, 15, 16, -1, 18, 19, 20, -1], dtype=np.int64
)

#: Metres per unit of the units BVH files are written in.
UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254}
#: Typical extent of a BVH rest skeleton (feet to head-top), m, for unit detection.
_TYPICAL_SKELETON_HEIGHT = 1.5

_ROTATION_CHANNELS = {"xrotation": "X", "yrotation": "Y", "zrotation": "Z"}
_POSITION_CHANNELS = {"xposition": 0, "yposition": 1, "zposition": 2}
_EPS = 1e-12


# --------------------------------------------------------------------------- name maps


def _normalise_name(name: str) -> str:
    """Joint name for matching: namespace dropped (``mixamorig:Hips``), lower case."""
    return name.rsplit(":", 1)[-1].strip().lower()


@dataclass(frozen=True)
class NameMap:
    """Joint names of one convention, per seatkit segment.

    Attributes
    ----------
    name : str
    segments : dict of str to tuple of str
        Segment name -> accepted joint names, in order of preference.
    known : tuple of str
        Extra joint names of this convention that are not mapped.
    bvh_channel_order : str
        Euler order (e.g. ``"ZXY"``) :func:`write_bvh` uses (``""``: ZXY).
    namespaces : tuple of str
        Name prefixes (``mixamorig`` of ``mixamorig:Hips``) typical of this
        convention: each joint carrying one counts once more when choosing a
        map, and :func:`write_bvh` writes the first.
    source : str
        File it came from.
    """

    name: str
    segments: dict
    known: tuple = ()
    bvh_channel_order: str = ""
    namespaces: tuple = ()
    source: str = ""
    description: str = ""

    def resolve(self, names: Sequence[str]) -> tuple[np.ndarray, int]:
        """Find each segment's joint among ``names``.

        Parameters
        ----------
        names : sequence of str
            Joint names of a file.

        Returns
        -------
        index : (21,) int64
            Index into ``names`` of each segment's joint, -1 where none.
        score : int
            How many of ``names`` this map recognises (mapped or known).
        """
        lookup: dict[str, int] = {}
        for i, n in enumerate(names):
            lookup.setdefault(_normalise_name(n), i)
        index = np.full(N_SEGMENTS, -1, dtype=np.int64)
        used: set[int] = set()
        for seg, aliases in self.segments.items():
            for alias in aliases:
                j = lookup.get(_normalise_name(alias))
                if j is not None and j not in used:
                    index[SEGMENT_INDEX[seg]] = j
                    used.add(j)
                    break
        recognised = {_normalise_name(a) for aliases in self.segments.values() for a in aliases}
        recognised |= {_normalise_name(a) for a in self.known}
        score = sum(1 for key in lookup if key in recognised)
        spaces = {ns.lower() for ns in self.namespaces}
        score += sum(1 for n in names if ":" in n and n.rsplit(":", 1)[0].strip().lower() in spaces)
        return index, score

    def missing(self, index: np.ndarray, required: Sequence[str] = REQUIRED_SEGMENTS) -> list[str]:
        """Required segments that ``index`` (from :meth:`resolve`) leaves without a joint."""
        return [s for s in required if index[SEGMENT_INDEX[s]] < 0]

    def overlaid(self, user: "NameMap") -> "NameMap":
        """This map with ``user``'s names first for the segments it lists."""
        segments = {k: tuple(v) for k, v in self.segments.items()}
        for seg, aliases in user.segments.items():
            segments[seg] = tuple(aliases) + tuple(a for a in segments.get(seg, ()) if a not in aliases)
        return NameMap(
            name=f"{user.name}+{self.name}",
            segments=segments,
            known=tuple(self.known) + tuple(user.known),
            bvh_channel_order=user.bvh_channel_order or self.bvh_channel_order,
            namespaces=tuple(user.namespaces) + tuple(self.namespaces),
            source=user.source,
            description=user.description or self.description,
        )


def _name_map_from_dict(data: Any, source: str) -> NameMap:
    if not isinstance(data, Mapping):
        msg = f"{source}: a name map must be a mapping with a 'segments' key, got {type(data).__name__}"
        raise InputError(msg)
    allowed = {"name", "description", "segments", "known", "bvh_channel_order", "namespaces", "base"}
    unknown_keys = set(data) - allowed
    if unknown_keys:
        msg = (
            f"{source}: unknown key(s) {', '.join(sorted(map(str, unknown_keys)))}; expected "
            f"{', '.join(sorted(allowed))}"
        )
        raise InputError(msg)
    raw = data.get("segments")
    if not isinstance(raw, Mapping):
        msg = f"{source}: 'segments' must map segment names to lists of joint names"
        raise InputError(msg)
    segments: dict[str, tuple[str, ...]] = {}
    for seg, aliases in raw.items():
        if seg not in SEGMENT_INDEX:
            msg = f"{source}: segments.{clip(seg)}: unknown segment; expected one of {', '.join(SEGMENTS)}"
            raise InputError(msg)
        if isinstance(aliases, str):
            aliases = [aliases]
        if not isinstance(aliases, list) or not all(isinstance(a, str) for a in aliases):
            msg = f"{source}: segments.{seg}: expected a list of joint names, got {quote(aliases)}"
            raise InputError(msg)
        segments[seg] = tuple(aliases)
    known = data.get("known") or []
    if not isinstance(known, list) or not all(isinstance(a, str) for a in known):
        msg = f"{source}: 'known' must be a list of joint names"
        raise InputError(msg)
    namespaces = data.get("namespaces") or []
    if not isinstance(namespaces, list) or not all(isinstance(a, str) for a in namespaces):
        msg = f"{source}: 'namespaces' must be a list of name prefixes"
        raise InputError(msg)
    order = str(data.get("bvh_channel_order", "")).upper()
    if order and sorted(order) != ["X", "Y", "Z"]:
        msg = f"{source}: bvh_channel_order: expected a permutation of XYZ, got {quote(order)}"
        raise InputError(msg)
    return NameMap(
        name=str(data.get("name", Path(source).stem)),
        segments=segments,
        known=tuple(known),
        bvh_channel_order=order,
        namespaces=tuple(namespaces),
        source=source,
        description=str(data.get("description", "")),
    )


@functools.lru_cache(maxsize=None)
def _builtin_name_map(name: str) -> NameMap:
    """A packaged name map, parsed once per process (every BVH and glTF load asks for them)."""
    builtin = data_path("name_maps", f"{name}.yaml")
    return _name_map_from_dict(yaml.load(builtin.read_text(encoding="utf-8"), Loader=_FAST_LOADER), f"{name}.yaml")


_FAST_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _read_yaml(path: Path):
    """A user's name map through seatkit's safe YAML loader (see seatkit.yamlio)."""
    from seatkit.yamlio import load_yaml

    try:
        return load_yaml(path, "name map").data
    except RecipeError as e:
        raise InputError(str(e)) from None


def load_name_map(name_map: str | Path | Mapping) -> NameMap:
    """Load a name map: a built-in name, a YAML path, or a dict.

    Parameters
    ----------
    name_map : str, Path or mapping
        ``"perception-neuron"``, ``"cmu"``, ``"mixamo"``, ``"gltf-default"``,
        a path to a YAML file, or the parsed mapping (see
        ``seatkit/data/name_maps/perception-neuron.yaml`` for the format).

    Returns
    -------
    NameMap
    """
    if isinstance(name_map, Mapping):
        return _name_map_from_dict(name_map, "<name map>")
    text_name = str(name_map)
    builtin = data_path("name_maps", f"{text_name}.yaml")
    if "/" not in text_name and not text_name.endswith((".yaml", ".yml")) and builtin.is_file():
        return _builtin_name_map(text_name)
    path = Path(name_map)
    if not path.is_file():
        names = sorted(p.stem for p in data_path("name_maps").glob("*.yaml"))
        msg = f"name map {text_name!r}: no such file, and not a built-in map ({', '.join(names)})"
        raise InputError(msg)
    return _name_map_from_dict(_read_yaml(path), str(path))


def candidate_maps(name_map, builtins: Sequence[str]) -> list[NameMap]:
    """The maps to try: built-ins, each overlaid with the user's map if given."""
    if name_map is None:
        return [load_name_map(b) for b in builtins]
    if isinstance(name_map, str) and name_map in builtins:
        return [load_name_map(name_map)]
    user_raw = name_map
    base = None
    if isinstance(name_map, Mapping):
        base = name_map.get("base")
    else:
        path = Path(name_map)
        if path.is_file():
            data = _read_yaml(path)
            if isinstance(data, Mapping):
                base = data.get("base")
    user = load_name_map(user_raw)
    if base is not None and str(base).lower() == "none":
        return [user]
    bases = [str(base)] if base is not None else list(builtins)
    return [load_name_map(b).overlaid(user) for b in bases]


def choose_map(names: Sequence[str], maps: Sequence[NameMap]) -> tuple[NameMap, np.ndarray]:
    """The map recognising most of ``names`` (ties: fewest missing segments, then order)."""
    best = None
    for rank, m in enumerate(maps):
        index, score = m.resolve(names)
        key = (score, -len(m.missing(index)), -rank)
        if best is None or key > best[0]:
            best = (key, m, index)
    return best[1], best[2]


# --------------------------------------------------------------------------- geometry helpers


def swing(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The smallest rotation turning direction ``u`` onto direction ``v``.

    Parameters
    ----------
    u, v : (3,) float64
        Non-zero vectors (a zero one gives the identity).

    Returns
    -------
    (3, 3) float64
    """
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if nu < _EPS or nv < _EPS:
        return np.eye(3)
    a, b = u / nu, v / nv
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        # opposite: half turn about any axis perpendicular to a
        perp = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        return Rotation.from_rotvec(np.pi * perp / np.linalg.norm(perp)).as_matrix()
    return Rotation.from_rotvec(axis / s * np.arctan2(s, c)).as_matrix()


def check_axes(left: np.ndarray, up: np.ndarray, extent: float, where: str) -> None:
    """Refuse a skeleton whose hips have no width or whose head sits on its hips.

    ``left`` (right hip to left hip) and ``up`` (hips to head) must be finite,
    at least a thousandth of the skeleton's ``extent`` long and not parallel
    (within 5 degrees): otherwise the body's axes, and every rotation derived
    from them, are undefined.

    Raises
    ------
    InputError
        Naming ``where`` (the file) and what is degenerate.
    """
    left, up = np.asarray(left, dtype=np.float64), np.asarray(up, dtype=np.float64)
    if not (np.isfinite(left).all() and np.isfinite(up).all() and np.isfinite(extent) and extent > 0):
        msg = f"{where}: the skeleton's joint positions are not finite"
        raise InputError(msg)
    nl, nu = float(np.linalg.norm(left)), float(np.linalg.norm(up))
    if nl < 1e-3 * extent:
        msg = f"{where}: degenerate skeleton: the left and right hip joints coincide (the body has no left-right axis)"
        raise InputError(msg)
    if nu < 1e-3 * extent:
        msg = f"{where}: degenerate skeleton: the head joint sits on the hips (the body has no up axis)"
        raise InputError(msg)
    if abs(float(left @ up)) > np.cos(np.radians(5.0)) * nl * nu:
        msg = f"{where}: degenerate skeleton: the hips' left-right axis is parallel to the hips-to-head axis"
        raise InputError(msg)


def facing_rotation(left: np.ndarray, up: np.ndarray, *, snap: bool = True) -> np.ndarray:
    """Rotation taking a skeleton's left and up directions to seatkit's +X and +Y.

    Parameters
    ----------
    left : (3,) float64
        Right hip to left hip (the body's left), any length.
    up : (3,) float64
        Hips to head.
    snap : bool
        Round to the nearest axis-aligned rotation (a signed permutation), so
        that a file whose axes are merely permuted is converted exactly.

    Returns
    -------
    A : (3, 3) float64
        ``A @ up`` is along +Y, ``A @ left`` along +X, the body faces +Z.
    """
    u = up / np.linalg.norm(up)
    lft = left - (left @ u) * u
    lft = lft / np.linalg.norm(lft)
    fwd = np.cross(lft, u)
    A = np.stack([lft, u, fwd])  # rows: where each seatkit axis comes from
    if snap:
        snapped = np.zeros((3, 3))
        cols = np.argmax(np.abs(A), axis=1)
        snapped[np.arange(3), cols] = np.sign(A[np.arange(3), cols])
        if len(set(cols.tolist())) == 3 and np.linalg.det(snapped) > 0.5:
            return snapped
    return A


# --------------------------------------------------------------------------- reading


@dataclass(frozen=True)
class BvhMotion:
    """A parsed BVH file.

    Attributes
    ----------
    path : str
    names : tuple of str
        Joint names (k of them), in file order.
    parents : (k,) int64
        Parent joint index, -1 for a root.
    offsets : (k, 3) float64
        Rest offset of each joint from its parent, file units.
    end_sites : (k, 3) float64
        Offset of the joint's End Site (NaN where it has none), file units.
    rotation_orders : tuple of str
        Euler order of each joint's rotation channels (``"ZXY"``; ``""`` if none).
    rotation_columns : tuple of (3,) int64 arrays
        Columns of ``frames`` holding each joint's rotation channels.
    position_columns : (3,) int64
        Columns of the first root's X, Y, Z position (-1 where absent).
    frames : (f, c) float64
        MOTION data, one row per frame.
    frame_time : float
        Seconds per frame.
    """

    path: str
    names: tuple
    parents: np.ndarray
    offsets: np.ndarray
    end_sites: np.ndarray
    rotation_orders: tuple
    rotation_columns: tuple
    position_columns: np.ndarray
    frames: np.ndarray
    frame_time: float
    meta: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.frames.shape[0])

    def rest_positions(self) -> np.ndarray:
        """(k, 3) float64 joint positions with every channel zero, file units."""
        pos = np.zeros_like(self.offsets)
        for j, p in enumerate(self.parents):
            pos[j] = self.offsets[j] + (pos[p] if p >= 0 else 0.0)
        return pos

    def local_rotations(self, frame: int) -> np.ndarray:
        """(k, 3, 3) float64 local rotation of every joint in ``frame``."""
        row = self.frames[frame]
        local = np.tile(np.eye(3), (len(self.names), 1, 1))
        for j, (order, cols) in enumerate(zip(self.rotation_orders, self.rotation_columns)):
            if order:
                # BVH channels compose left to right in the listed order:
                # Zrotation Xrotation Yrotation -> Rz @ Rx @ Ry, i.e. intrinsic "ZXY"
                angles = np.where(cols >= 0, row[cols], 0.0)  # column -1: channel absent
                local[j] = Rotation.from_euler(order, angles, degrees=True).as_matrix()
        return local

    def global_transforms(self, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """World rotation (k, 3, 3) and position (k, 3) of every joint, file units.

        The root's position is its offset plus its position channels.
        """
        local = self.local_rotations(frame)
        glob = np.empty_like(local)
        pos = np.empty_like(self.offsets)
        root_shift = np.zeros(3)
        have = self.position_columns >= 0
        root_shift[have] = self.frames[frame, self.position_columns[have]]
        for j, p in enumerate(self.parents):
            if p < 0:
                glob[j] = local[j]
                pos[j] = self.offsets[j] + root_shift
            else:
                glob[j] = glob[p] @ local[j]
                pos[j] = pos[p] + glob[p] @ self.offsets[j]
        return glob, pos

    def extent(self) -> float:
        """Largest extent of the rest skeleton (joints and end sites), file units."""
        rest = self.rest_positions()
        ends = rest + np.nan_to_num(self.end_sites)
        pts = np.concatenate([rest, ends[~np.isnan(self.end_sites).any(axis=1)]])
        return float((pts.max(axis=0) - pts.min(axis=0)).max())


#: Most joints a BVH skeleton may have (a full-body capture with fingers has
#: about 70; more is not a human and a long chain would be slow to pose).
MAX_JOINTS = 1000
#: Largest OFFSET coordinate, file units (a kilometre in millimetres).
MAX_OFFSET = 1e6
#: Largest MOTION value: angles in degrees, positions in file units.
MAX_CHANNEL_VALUE = 1e7


def _float(token: str, path, line: int, what: str) -> float:
    try:
        value = float(token)
    except ValueError:
        msg = f"{path}:{line}: {what}: expected a number, got {quote(token)}"
        raise InputError(msg) from None
    if not np.isfinite(value):
        msg = f"{path}:{line}: {what}: expected a finite number, got {quote(token)}"
        raise InputError(msg)
    return value


def read_bvh(path: str | Path) -> BvhMotion:
    """Parse a BVH file.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    BvhMotion

    Raises
    ------
    InputError
        Unreadable file, malformed hierarchy, or MOTION data that is not
        numeric or has the wrong number of values (the message gives the line).
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        msg = f"{path}: cannot read BVH file: {e.strerror or e}"
        raise InputError(msg) from e
    try:
        text = decode_text(data, str(path), "BVH file")
    except RecipeError as e:
        raise InputError(str(e)) from None
    lines = text.splitlines()
    # tokens of the HIERARCHY section with their (1-based) line numbers
    tokens: list[tuple[str, int]] = []
    motion_line = None
    joints_seen = 0
    for lineno, line in enumerate(lines, start=1):
        if line.strip().upper().startswith("MOTION"):
            motion_line = lineno
            break
        words = line.replace("{", " { ").replace("}", " } ").split()
        joints_seen += sum(1 for t in words if t.upper() in ("ROOT", "JOINT"))
        if joints_seen > MAX_JOINTS:  # refused before the rest of a huge file is tokenised
            msg = f"{path}:{lineno}: more than {MAX_JOINTS} joints; not a human skeleton seatkit reads"
            raise InputError(msg)
        tokens.extend((t, lineno) for t in words)
    if not tokens or tokens[0][0].upper() != "HIERARCHY":
        msg = f"{path}:1: not a BVH file: expected HIERARCHY"
        raise InputError(msg)
    if motion_line is None:
        msg = f"{path}: no MOTION section"
        raise InputError(msg)

    names: list[str] = []
    parents: list[int] = []
    offsets: list[np.ndarray] = []
    end_sites: list[np.ndarray] = []
    orders: list[str] = []
    rot_cols: list[np.ndarray] = []
    position_columns = np.full(3, -1, dtype=np.int64)
    n_channels = 0
    stack: list[int] = []  # open joints; -2 marks an End Site block
    open_joints: list[int] = []  # the joints of ``stack`` (without End Sites): parents in O(1)
    i = 1

    def expect(k: int, what: str) -> list[tuple[str, int]]:
        if i + k > len(tokens):
            msg = f"{path}:{tokens[-1][1]}: unexpected end of HIERARCHY while reading {what}"
            raise InputError(msg)
        return tokens[i : i + k]

    pending: int | None = None  # joint (or -2) whose '{' is expected next
    while i < len(tokens):
        tok, ln = tokens[i]
        key = tok.upper()
        if key in ("ROOT", "JOINT"):
            (name, _), = expect(2, key)[1:]
            if key == "JOINT" and not open_joints:
                msg = f"{path}:{ln}: JOINT {clip(name)} outside any ROOT"
                raise InputError(msg)
            if len(names) >= MAX_JOINTS:
                msg = f"{path}:{ln}: more than {MAX_JOINTS} joints; not a human skeleton seatkit reads"
                raise InputError(msg)
            if key == "ROOT" and stack:
                msg = f"{path}:{ln}: ROOT {clip(name)} inside another joint"
                raise InputError(msg)
            parent = open_joints[-1] if key == "JOINT" else -1
            names.append(name)
            parents.append(parent)
            offsets.append(np.zeros(3))
            end_sites.append(np.full(3, np.nan))
            orders.append("")
            rot_cols.append(np.zeros(0, dtype=np.int64))
            pending = len(names) - 1
            i += 2
        elif key == "END":
            expect(2, "End Site")
            pending = -2
            i += 2
        elif key == "{":
            if pending is None:
                msg = f"{path}:{ln}: unexpected '{{'"
                raise InputError(msg)
            stack.append(pending)
            if pending >= 0:
                open_joints.append(pending)
            pending = None
            i += 1
        elif key == "}":
            if not stack:
                msg = f"{path}:{ln}: unbalanced '}}'"
                raise InputError(msg)
            if stack.pop() >= 0:
                open_joints.pop()
            i += 1
        elif key == "OFFSET":
            vals = expect(4, "OFFSET")[1:]
            xyz = np.array([_float(t, path, n, "OFFSET") for t, n in vals])
            if not stack:
                msg = f"{path}:{ln}: OFFSET outside a joint"
                raise InputError(msg)
            if np.abs(xyz).max() > MAX_OFFSET:
                msg = f"{path}:{ln}: OFFSET {clip(' '.join(t for t, _ in vals))}: larger than {MAX_OFFSET:g} file units"
                raise InputError(msg)
            if stack[-1] == -2:
                end_sites[open_joints[-1]] = xyz
            else:
                offsets[stack[-1]] = xyz
            i += 4
        elif key == "CHANNELS":
            (count_tok, _), = expect(2, "CHANNELS")[1:]
            try:
                count = int(count_tok)
            except ValueError:
                count = -1
            if not 0 <= count <= 6:
                msg = f"{path}:{ln}: CHANNELS: expected a channel count from 0 to 6, got {quote(count_tok)}"
                raise InputError(msg) from None
            chans = [t for t, _ in expect(2 + count, "CHANNELS")[2:]]
            if not stack or stack[-1] < 0:
                msg = f"{path}:{ln}: CHANNELS outside a joint"
                raise InputError(msg)
            joint = stack[-1]
            order, cols = "", []
            for c, chan in enumerate(chans):
                low = chan.lower()
                if low in _ROTATION_CHANNELS:
                    order += _ROTATION_CHANNELS[low]
                    cols.append(n_channels + c)
                elif low in _POSITION_CHANNELS:
                    if joint == 0:  # position channels of other joints are ignored
                        position_columns[_POSITION_CHANNELS[low]] = n_channels + c
                else:
                    msg = f"{path}:{ln}: joint {clip(names[joint])}: unknown channel {quote(chan)}"
                    raise InputError(msg)
            if order and len(set(order)) != len(order):
                msg = f"{path}:{ln}: joint {clip(names[joint])}: repeated rotation channel in {clip(' '.join(chans))}"
                raise InputError(msg)
            if order and len(order) != 3:
                # fewer than three rotation channels: pad with unused axes at zero
                order += "".join(a for a in "XYZ" if a not in order)
                cols += [-1] * (3 - len(cols))
            orders[joint] = order
            rot_cols[joint] = np.array(cols, dtype=np.int64)
            n_channels += count
            i += 2 + count
        else:
            msg = f"{path}:{ln}: unexpected {quote(tok)} in HIERARCHY"
            raise InputError(msg)
    if stack:
        msg = f"{path}: HIERARCHY ends with {len(stack)} unclosed '{{'"
        raise InputError(msg)
    if not names:
        msg = f"{path}: HIERARCHY has no joints"
        raise InputError(msg)

    # MOTION: "Frames: n", "Frame Time: t", then one line of numbers per frame
    header: dict[str, tuple[str, int]] = {}
    ln = motion_line
    while ln < len(lines) and len(header) < 2:
        line = lines[ln].strip()
        ln += 1
        if not line:
            continue
        head, _, value = line.partition(":")
        head = head.strip().lower()
        if head not in ("frames", "frame time"):
            msg = f"{path}:{ln}: expected 'Frames:' and 'Frame Time:' after MOTION, got {quote(line)}"
            raise InputError(msg)
        header[head] = (value.strip(), ln)
    if len(header) < 2:
        msg = f"{path}: MOTION needs 'Frames:' and 'Frame Time:'"
        raise InputError(msg)
    try:
        n_frames = int(header["frames"][0])
    except ValueError:
        msg = f"{path}:{header['frames'][1]}: Frames: expected a whole number, got {quote(header['frames'][0])}"
        raise InputError(msg) from None
    frame_time = _float(header["frame time"][0], path, header["frame time"][1], "Frame Time")
    data_lines = [(k + 1, lines[k]) for k in range(ln, len(lines)) if lines[k].strip()]
    if len(data_lines) < n_frames or n_frames < 1:
        msg = f"{path}: MOTION declares {n_frames} frames but has {len(data_lines)} lines of data"
        raise InputError(msg)
    data_lines = data_lines[:n_frames]
    try:
        # fast path: every number at once
        flat = np.array(" ".join(t for _, t in data_lines).split(), dtype=np.float64)
        ok = flat.size == n_frames * n_channels and bool((np.abs(flat) <= MAX_CHANNEL_VALUE).all())
    except ValueError:
        ok = False
    if not ok:
        # slow path only to name the first bad line
        for k, (lineno, line) in enumerate(data_lines):
            parts = line.split()
            if len(parts) != n_channels:
                msg = f"{path}:{lineno}: frame {k}: expected {n_channels} numbers (one per channel), got {len(parts)}"
                raise InputError(msg)
            for c, t in enumerate(parts):
                if abs(_float(t, path, lineno, f"frame {k}, channel {c + 1}")) > MAX_CHANNEL_VALUE:
                    msg = f"{path}:{lineno}: frame {k}, channel {c + 1}: {clip(t)} is beyond +-{MAX_CHANNEL_VALUE:g}"
                    raise InputError(msg)
    frames = flat.reshape(n_frames, n_channels)
    return BvhMotion(
        path=str(path),
        names=tuple(names),
        parents=np.array(parents, dtype=np.int64),
        offsets=np.array(offsets),
        end_sites=np.array(end_sites),
        rotation_orders=tuple(orders),
        rotation_columns=tuple(rot_cols),
        position_columns=position_columns,
        frames=frames,
        frame_time=frame_time,
    )


def detect_unit(motion: BvhMotion) -> str:
    """Guess the length unit of a BVH from its rest skeleton's size (see module doc)."""
    extent = motion.extent()
    if extent <= 0:
        return "m"
    ratio = {u: abs(np.log(extent * s / _TYPICAL_SKELETON_HEIGHT)) for u, s in UNITS.items()}
    return min(ratio, key=ratio.get)


def _next_mapped(s: int, index: np.ndarray) -> int:
    """Nearest mapped segment down the main chain from ``s`` (-1 if none)."""
    d = CHAIN_CHILD[s]
    while d >= 0 and index[d] < 0:
        d = CHAIN_CHILD[d]
    return int(d)


def load_bvh(
    path: str | Path,
    *,
    frame: int = 0,
    rig: RiggedBody | None = None,
    name_map: str | Path | Mapping | None = None,
    root_motion: bool = False,
    unit: str = "auto",
) -> Pose:
    """One frame of a BVH file as a Pose of ``rig``.

    Parameters
    ----------
    path : str or Path
    frame : int
        0-based frame number (negative counts from the end).
    rig : RiggedBody, optional
        Body the pose is for: its rest bones are matched to the BVH's rest
        bones (see the module doc). Without it the BVH rest pose is taken to
        be the rig's rest pose.
    name_map : str, Path or mapping, optional
        A built-in map name, a YAML file or a dict laid over the built-in maps.
    root_motion : bool
        Give the pose the root's translation since frame 0 (m).
    unit : {"auto", "m", "cm", "mm", "inch"}
        Length unit of the file (only root motion depends on it).

    Returns
    -------
    Pose
        Named ``"<file name>#<frame>"``.

    Raises
    ------
    InputError
        Bad file, frame out of range, or required joints missing (named).
    """
    if unit != "auto" and unit not in UNITS:
        msg = f"unit must be one of auto, {', '.join(UNITS)}; got {unit!r}"
        raise InputError(msg)
    motion = read_bvh(path)
    n = motion.n_frames
    if not -n <= frame < n:
        msg = f"{path}: frame {frame} out of range; the file has {n} frames (0..{n - 1})"
        raise InputError(msg)
    frame = frame % n
    nm, index = choose_map(motion.names, candidate_maps(name_map, BUILTIN_BVH_MAPS))
    missing = nm.missing(index)
    if missing:
        wanted = "; ".join(f"{s} ({' or '.join(nm.segments.get(s, ()))})" for s in missing)
        msg = f"{path}: BVH lacks joints needed for segment(s) {wanted} (name map {nm.name})"
        raise InputError(msg)

    rest = motion.rest_positions()
    glob, pos = motion.global_transforms(frame)
    # axis conversion from the rest skeleton (see module doc, step 2)
    left = rest[index[SEGMENT_INDEX["LeftUpLeg"]]] - rest[index[SEGMENT_INDEX["RightUpLeg"]]]
    up = rest[index[SEGMENT_INDEX["Head"]]] - rest[index[0]]
    check_axes(left, up, motion.extent(), str(path))
    A = facing_rotation(left, up)
    glob = A @ glob @ A.T
    pos = pos @ A.T
    rest = rest @ A.T

    world = np.empty((N_SEGMENTS, 3, 3))
    correction = np.empty((N_SEGMENTS, 3, 3))
    for s in range(N_SEGMENTS):
        j = index[s]
        parent = PARENTS[s]
        if s == 0:
            correction[s] = np.eye(3)
            world[s] = glob[j]
            continue
        if j < 0:
            correction[s] = correction[parent]
            world[s] = world[parent]
            continue
        d = _next_mapped(s, index)
        if d < 0:
            # end segment: keeps its parent's rest correction
            correction[s] = correction[parent]
            world[s] = glob[j] @ correction[s]
            continue
        bvh_rest_bone = rest[index[d]] - rest[j]
        correction[s] = swing(rig.joints[d] - rig.joints[s], bvh_rest_bone) if rig is not None else np.eye(3)
        chord = swing(glob[j] @ bvh_rest_bone, pos[index[d]] - pos[j])
        world[s] = chord @ glob[j] @ correction[s]
    # relative rotations R_s = G_parent^T G_s
    relative = world.copy()
    relative[1:] = np.einsum("sji,sjk->sik", world[PARENTS[1:]], world[1:])
    if not np.isfinite(relative).all():
        msg = f"{path}: frame {frame}: degenerate joint rotations (not finite); the skeleton or MOTION data is malformed"
        raise InputError(msg)
    rotations = Rotation.from_matrix(relative).as_rotvec()

    translation = np.zeros(3)
    if root_motion:
        scale = UNITS[detect_unit(motion) if unit == "auto" else unit]
        _, pos0 = motion.global_transforms(0)
        translation = (pos[index[0]] - pos0[index[0]] @ A.T) * scale
    return Pose(rotations, translation, f"{Path(path).name}#{frame}")


# --------------------------------------------------------------------------- writing


def _fmt(values) -> str:
    return " ".join(f"{v:.10f}".rstrip("0").rstrip(".") if v != 0 else "0" for v in np.asarray(values).ravel())


def write_bvh(
    path: str | Path,
    poses: Pose | Sequence[Pose],
    rig: RiggedBody,
    naming: str | Path | Mapping = "perception-neuron",
    *,
    frame_time: float = 1.0 / 30.0,
) -> Path:
    """Write poses of ``rig`` as a BVH file.

    The BVH rest pose is the rig's rest pose (offsets in centimetres, +Y up,
    facing +Z), every joint has three rotation channels in the naming's
    ``bvh_channel_order`` (degrees) and the root also three position
    channels (its absolute position, cm; its OFFSET is zero). The head, hands and feet get End Sites at
    the rig's tips. A segment the naming has no joint for (Spine2 in CMU and
    Mixamo) is left out and its rotation is composed into its children's;
    that is exact when its rotation is zero.

    Parameters
    ----------
    path : str or Path
    poses : Pose or sequence of Pose
        One frame per pose.
    rig : RiggedBody
    naming : str, Path or mapping
        Name map whose first name per segment is written.
    frame_time : float
        Seconds per frame.

    Returns
    -------
    Path
    """
    from seatkit.io import write_bytes_atomic

    poses = [poses] if isinstance(poses, Pose) else list(poses)
    if not poses:
        msg = "write_bvh needs at least one pose"
        raise InputError(msg)
    nm = load_name_map(naming)
    prefix = f"{nm.namespaces[0]}:" if nm.namespaces else ""
    names = {s: prefix + nm.segments[SEGMENTS[s]][0] for s in range(N_SEGMENTS) if nm.segments.get(SEGMENTS[s])}
    if 0 not in names:
        msg = f"name map {nm.name} has no name for Hips; cannot write a BVH"
        raise InputError(msg)
    order = nm.bvh_channel_order or "ZXY"
    cm = 100.0
    joints = np.asarray(rig.joints, dtype=np.float64)
    tips = np.asarray(rig.tips, dtype=np.float64)
    children = {s: [int(c) for c in np.flatnonzero(PARENTS == s)] for s in range(N_SEGMENTS)}

    # the written joints, in depth-first order, with the segments folded into each
    written: list[tuple[int, int, list[int]]] = []  # (segment, written parent segment, folded chain)
    out: list[str] = ["HIERARCHY"]
    rot_channels = " ".join(f"{a}rotation" for a in order)

    def emit(s: int, emitted_parent: int, folded: list[int], depth: int) -> None:
        pad = "  " * depth
        if s in names:
            written.append((s, emitted_parent, folded + [s]))
            if s == 0:
                out.append(f"ROOT {names[s]}")
                out.append("{")
                # root OFFSET 0 and absolute position channels: readers that
                # add the offset and readers that ignore it agree
                out.append(f"{pad}  OFFSET 0 0 0")
                out.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rot_channels}")
            else:
                out.append(f"{pad}JOINT {names[s]}")
                out.append(f"{pad}{{")
                out.append(f"{pad}  OFFSET {_fmt((joints[s] - joints[emitted_parent]) * cm)}")
                out.append(f"{pad}  CHANNELS 3 {rot_channels}")
            kids = children[s]
            if not kids:
                out.append(f"{pad}  End Site")
                out.append(f"{pad}  {{")
                out.append(f"{pad}    OFFSET {_fmt((tips[s] - joints[s]) * cm)}")
                out.append(f"{pad}  }}")
            for c in kids:
                emit(c, s, [], depth + 1)
            out.append(f"{pad}}}")
        else:
            for c in children[s]:
                emit(c, emitted_parent, folded + [s], depth)

    emit(0, -1, [], 0)
    out.append("MOTION")
    out.append(f"Frames: {len(poses)}")
    out.append(f"Frame Time: {frame_time:.8f}")
    for pose in poses:
        local = Rotation.from_rotvec(pose.rotations).as_matrix()
        row: list[np.ndarray] = [(joints[0] + pose.translation) * cm]
        for _, _, chain in written:
            m = np.eye(3)
            for seg in chain:
                m = m @ local[seg]
            with warnings.catch_warnings():
                # gimbal lock: scipy still returns angles that give the same rotation
                warnings.simplefilter("ignore", UserWarning)
                row.append(Rotation.from_matrix(m).as_euler(order, degrees=True))
        out.append(_fmt(np.concatenate(row)))
    path = Path(path)
    write_bytes_atomic(path, ("\n".join(out) + "\n").encode("utf-8"))
    return path
