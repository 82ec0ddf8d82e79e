"""BVH motion files: read a frame as a seatkit :class:`~seatkit.model.Pose`, write poses.

Reading
-------
:func:`read_bvh` parses HIERARCHY and MOTION (any channel order, Euler
rotation channels in degrees, position channels on the root) into a
:class:`BvhMotion`. :func:`load_bvh` turns one frame into a Pose for a rig:

1. **Names** (:mod:`seatkit.body.name_maps`). A name map (YAML, ``seatkit/data/name_maps/``) lists for each of
   the 21 segments the BVH joint names that drive it. The built-in
   Perception Neuron, CMU and Mixamo maps are tried and the one that
   recognises most joint names of the file wins (each map also lists the
   extra joints of its convention: fingers, toes, end joints). Names match
   case-insensitively after dropping a namespace prefix (``mixamorig:``). A
   user map (a YAML path or a dict) is laid over every built-in one: its
   names come first for the segments it lists (``base: cmu`` picks the
   built-in map it extends; ``base: none`` uses it alone).
2. **Axes** (:mod:`seatkit.body.retarget`). The BVH rest skeleton (every channel zero) gives the body's up
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

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from seatkit.body.name_maps import BUILTIN_BVH_MAPS, candidate_maps, choose_map, load_name_map
from seatkit.body.retarget import CHAIN_CHILD, check_axes, facing_rotation, swing
from seatkit.errors import InputError, RecipeError
from seatkit.messages import clip, quote
from seatkit.model import Pose, RiggedBody
from seatkit.skeleton import N_SEGMENTS, PARENTS, SEGMENT_INDEX, SEGMENTS
from seatkit.yamlio import decode_text

__all__ = [
    "UNITS",
    "BvhMotion",
    "read_bvh",
    "detect_unit",
    "load_bvh",
    "write_bvh",
]

#: Metres per unit of the units BVH files are written in.
UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254}
#: Typical extent of a BVH rest skeleton (feet to head-top), m, for unit detection.
_TYPICAL_SKELETON_HEIGHT = 1.5

_ROTATION_CHANNELS = {"xrotation": "X", "yrotation": "Y", "zrotation": "Z"}
_POSITION_CHANNELS = {"xposition": 0, "yposition": 1, "zposition": 2}


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


def _read_lines(path: Path) -> list[str]:
    """The lines of a BVH file, with one-line errors for an unreadable or non-UTF-8 file."""
    from seatkit.io import MAX_FILE_BYTES, read_user_file

    data = read_user_file(path, "BVH file", max_bytes=MAX_FILE_BYTES["BVH"])
    try:
        text = decode_text(data, str(path), "BVH file")
    except RecipeError as e:
        raise InputError(str(e)) from None
    return text.splitlines()


def _hierarchy_tokens(path: Path, lines: list[str]) -> tuple[list[tuple[str, int]], int]:
    """The tokens of the HIERARCHY section with their (1-based) lines, and the line of MOTION."""
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
    return tokens, motion_line


class _HierarchyParser:
    """The joints of a HIERARCHY section, read token by token (one method per keyword)."""

    def __init__(self, path: Path, tokens: list[tuple[str, int]]):
        self.path, self.tokens = path, tokens
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[np.ndarray] = []
        self.end_sites: list[np.ndarray] = []
        self.orders: list[str] = []
        self.rot_cols: list[np.ndarray] = []
        self.position_columns = np.full(3, -1, dtype=np.int64)
        self.n_channels = 0
        self.stack: list[int] = []  # open joints; -2 marks an End Site block
        self.open_joints: list[int] = []  # the joints of ``stack`` (without End Sites): parents in O(1)
        self.pending: int | None = None  # joint (or -2) whose '{' is expected next
        self.i = 1

    def parse(self) -> "_HierarchyParser":
        keywords = {
            "ROOT": self._joint,
            "JOINT": self._joint,
            "END": self._end_site,
            "{": self._open,
            "}": self._close,
            "OFFSET": self._offset,
            "CHANNELS": self._channels,
        }
        while self.i < len(self.tokens):
            tok, ln = self.tokens[self.i]
            step = keywords.get(tok.upper())
            if step is None:
                msg = f"{self.path}:{ln}: unexpected {quote(tok)} in HIERARCHY"
                raise InputError(msg)
            self.i += step(tok.upper(), ln)
        if self.stack:
            msg = f"{self.path}: HIERARCHY ends with {len(self.stack)} unclosed '{{'"
            raise InputError(msg)
        if not self.names:
            msg = f"{self.path}: HIERARCHY has no joints"
            raise InputError(msg)
        return self

    def _expect(self, k: int, what: str) -> list[tuple[str, int]]:
        if self.i + k > len(self.tokens):
            msg = f"{self.path}:{self.tokens[-1][1]}: unexpected end of HIERARCHY while reading {what}"
            raise InputError(msg)
        return self.tokens[self.i : self.i + k]

    def _joint(self, key: str, ln: int) -> int:
        (name, _), = self._expect(2, key)[1:]
        if key == "JOINT" and not self.open_joints:
            msg = f"{self.path}:{ln}: JOINT {clip(name)} outside any ROOT"
            raise InputError(msg)
        if len(self.names) >= MAX_JOINTS:
            msg = f"{self.path}:{ln}: more than {MAX_JOINTS} joints; not a human skeleton seatkit reads"
            raise InputError(msg)
        if key == "ROOT" and self.stack:
            msg = f"{self.path}:{ln}: ROOT {clip(name)} inside another joint"
            raise InputError(msg)
        self.parents.append(self.open_joints[-1] if key == "JOINT" else -1)
        self.names.append(name)
        self.offsets.append(np.zeros(3))
        self.end_sites.append(np.full(3, np.nan))
        self.orders.append("")
        self.rot_cols.append(np.zeros(0, dtype=np.int64))
        self.pending = len(self.names) - 1
        return 2

    def _end_site(self, key: str, ln: int) -> int:
        self._expect(2, "End Site")
        self.pending = -2
        return 2

    def _open(self, key: str, ln: int) -> int:
        if self.pending is None:
            msg = f"{self.path}:{ln}: unexpected '{{'"
            raise InputError(msg)
        self.stack.append(self.pending)
        if self.pending >= 0:
            self.open_joints.append(self.pending)
        self.pending = None
        return 1

    def _close(self, key: str, ln: int) -> int:
        if not self.stack:
            msg = f"{self.path}:{ln}: unbalanced '}}'"
            raise InputError(msg)
        if self.stack.pop() >= 0:
            self.open_joints.pop()
        return 1

    def _offset(self, key: str, ln: int) -> int:
        vals = self._expect(4, "OFFSET")[1:]
        xyz = np.array([_float(t, self.path, n, "OFFSET") for t, n in vals])
        if not self.stack:
            msg = f"{self.path}:{ln}: OFFSET outside a joint"
            raise InputError(msg)
        if np.abs(xyz).max() > MAX_OFFSET:
            msg = f"{self.path}:{ln}: OFFSET {clip(' '.join(t for t, _ in vals))}: larger than {MAX_OFFSET:g} file units"
            raise InputError(msg)
        if self.stack[-1] == -2:
            self.end_sites[self.open_joints[-1]] = xyz
        else:
            self.offsets[self.stack[-1]] = xyz
        return 4

    def _channels(self, key: str, ln: int) -> int:
        (count_tok, _), = self._expect(2, "CHANNELS")[1:]
        try:
            count = int(count_tok)
        except ValueError:
            count = -1
        if not 0 <= count <= 6:
            msg = f"{self.path}:{ln}: CHANNELS: expected a channel count from 0 to 6, got {quote(count_tok)}"
            raise InputError(msg) from None
        chans = [t for t, _ in self._expect(2 + count, "CHANNELS")[2:]]
        if not self.stack or self.stack[-1] < 0:
            msg = f"{self.path}:{ln}: CHANNELS outside a joint"
            raise InputError(msg)
        joint = self.stack[-1]
        order, cols = "", []
        for c, chan in enumerate(chans):
            low = chan.lower()
            if low in _ROTATION_CHANNELS:
                order += _ROTATION_CHANNELS[low]
                cols.append(self.n_channels + c)
            elif low in _POSITION_CHANNELS:
                if joint == 0:  # position channels of other joints are ignored
                    self.position_columns[_POSITION_CHANNELS[low]] = self.n_channels + c
            else:
                msg = f"{self.path}:{ln}: joint {clip(self.names[joint])}: unknown channel {quote(chan)}"
                raise InputError(msg)
        if order and len(set(order)) != len(order):
            msg = f"{self.path}:{ln}: joint {clip(self.names[joint])}: repeated rotation channel in {clip(' '.join(chans))}"
            raise InputError(msg)
        if order and len(order) != 3:
            # fewer than three rotation channels: pad with unused axes at zero
            order += "".join(a for a in "XYZ" if a not in order)
            cols += [-1] * (3 - len(cols))
        self.orders[joint] = order
        self.rot_cols[joint] = np.array(cols, dtype=np.int64)
        self.n_channels += count
        return 2 + count


def _motion_header(path: Path, lines: list[str], motion_line: int) -> tuple[int, float, int]:
    """``Frames:`` and ``Frame Time:`` after MOTION, and the index of the line after them."""
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
    return n_frames, frame_time, ln


def _motion_frames(path: Path, lines: list[str], start: int, n_frames: int, n_channels: int) -> np.ndarray:
    """(n_frames, n_channels) float64: one line of numbers per frame from ``lines[start]`` on."""
    data_lines = [(k + 1, lines[k]) for k in range(start, len(lines)) if lines[k].strip()]
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
    return flat.reshape(n_frames, n_channels)


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
    lines = _read_lines(path)
    tokens, motion_line = _hierarchy_tokens(path, lines)
    joints = _HierarchyParser(path, tokens).parse()
    n_frames, frame_time, start = _motion_header(path, lines, motion_line)
    return BvhMotion(
        path=str(path),
        names=tuple(joints.names),
        parents=np.array(joints.parents, dtype=np.int64),
        offsets=np.array(joints.offsets),
        end_sites=np.array(joints.end_sites),
        rotation_orders=tuple(joints.orders),
        rotation_columns=tuple(joints.rot_cols),
        position_columns=joints.position_columns,
        frames=_motion_frames(path, lines, start, n_frames, joints.n_channels),
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
