"""Random plausible poses: seated, reclined, crossed-leg and leaning forward.

Each family draws every joint angle uniformly from a range (degrees, the
pose files' intrinsic X-Y-Z Euler angles relative to the parent segment, see
docs/poses.md, where the ranges and their sources are listed). The ranges
stay inside the normal active range of motion of each joint and around the
postures people take on chairs; they are centred on the library poses.
Right and left legs draw their own angles (a person rarely sits
symmetrically); the crossed-leg family crosses a randomly chosen leg.

``unsupported`` families (sitting sideways, feet tucked under the thighs,
kneeling on the seat) exist so that a benchmark exercises the refusal rule
of :mod:`seatkit.supportability` too; they are not drawn unless asked for.

::

    from seatkit.body.generator import draw_poses
    for drawn in draw_poses(200, seed=0):        # DrawnPose
        body = pose_rig(rig, drawn.pose)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from seatkit.body.poses import euler_to_rotvec
from seatkit.model import Pose
from seatkit.skeleton import N_SEGMENTS, SEGMENT_INDEX, SEGMENTS

__all__ = ["FAMILIES", "UNSUPPORTED_FAMILIES", "DrawnPose", "draw_pose", "draw_poses", "pose_yaml", "yaml_float"]

#: The families the chair is meant to support, drawn in turn by :func:`draw_poses`.
FAMILIES = ("seated", "reclined", "crossed-legs", "leaning-forward")
#: Families the 3x7 chair cannot support (paper Sec. 6): for testing the refusal.
UNSUPPORTED_FAMILIES = ("sideways", "feet-tucked", "kneeling")


@dataclass(frozen=True)
class DrawnPose:
    """One random pose.

    Attributes
    ----------
    name : str
        ``<family>-<index>``.
    family : str
    angles : (21, 3) float64
        Euler angles per segment, degrees (row 0 the root orientation).
    pose : Pose
    """

    name: str
    family: str
    angles: np.ndarray
    pose: Pose


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _mirror(x: float, y: float, z: float) -> tuple[float, float, float]:
    """The left-side angles of a right-side rotation (mirror across the sagittal plane)."""
    return x, -y, -z


class _Angles:
    def __init__(self):
        self.a = np.zeros((N_SEGMENTS, 3))

    def set(self, seg: str, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> None:
        self.a[SEGMENT_INDEX[seg]] = (x, y, z)

    def side(self, side: str, seg: str, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> None:
        """Set ``<Right|Left><seg>`` from right-side angles (mirrored for the left)."""
        if side == "Right":
            self.set("Right" + seg, x, y, z)
        else:
            self.set("Left" + seg, *_mirror(x, y, z))


def _legs_seated(rng, A: _Angles, side: str, thigh_total: float, root_x: float) -> None:
    """One leg of an ordinary sitting posture; ``thigh_total`` is the thigh's angle from vertical (deg, 90 = level)."""
    A.side(side, "UpLeg", -thigh_total - root_x, _u(rng, -10, 10), _u(rng, -15, 3))
    A.side(side, "Leg", _u(rng, 60, 115))
    A.side(side, "Foot", _u(rng, -15, 20))


def _spine(rng, A: _Angles, lo: float, hi: float) -> None:
    for seg in ("Spine", "Spine1", "Spine2", "Spine3"):
        A.set(seg, _u(rng, lo, hi), _u(rng, -3, 3), _u(rng, -3, 3))


def _arms(rng, A: _Angles, choice: str | None = None) -> None:
    """Arms in one of four everyday placements, jittered."""
    choice = choice or str(rng.choice(["thighs", "armrests", "hanging", "lap"]))
    for side in ("Right", "Left"):
        if choice == "thighs":  # hands on the thighs (upright-sitting)
            A.side(side, "Arm", _u(rng, -30, -10), 0.0, _u(rng, 82, 90))
            A.side(side, "ForeArm", 0.0, _u(rng, 35, 60), _u(rng, 0, 15))
        elif choice == "armrests":  # forearms level, elbows bent (armrest-sitting)
            A.side(side, "Arm", _u(rng, -8, 8), 0.0, _u(rng, 70, 80))
            A.side(side, "ForeArm", 0.0, _u(rng, 80, 95), 0.0)
        elif choice == "hanging":  # arms along the body
            A.side(side, "Arm", _u(rng, -10, 10), 0.0, _u(rng, 80, 88))
            A.side(side, "ForeArm", 0.0, _u(rng, 0, 25), 0.0)
        else:  # hands together in the lap
            A.side(side, "Arm", _u(rng, -35, -20), 0.0, _u(rng, 75, 85))
            A.side(side, "ForeArm", 0.0, _u(rng, 65, 85), _u(rng, 0, 15))


def _head(rng, A: _Angles, lo: float, hi: float) -> None:
    A.set("Neck", _u(rng, lo, hi))
    A.set("Head", _u(rng, lo, hi))


def _seated(rng) -> np.ndarray:
    A = _Angles()
    root_x = _u(rng, -12, 8)
    A.set("Hips", root_x, _u(rng, -5, 5))
    base = _u(rng, 80, 100)
    for side in ("Right", "Left"):
        _legs_seated(rng, A, side, base + _u(rng, -5, 5), root_x)
    _spine(rng, A, -4, 6)
    _head(rng, A, -10, 15)
    _arms(rng, A)
    return A.a


def _reclined(rng) -> np.ndarray:
    A = _Angles()
    root_x = _u(rng, -45, -15)
    A.set("Hips", root_x, _u(rng, -5, 5))
    elev = _u(rng, -5, 25)  # thighs raised above level (a lounger)
    for side in ("Right", "Left"):
        A.side(side, "UpLeg", -(90 + elev + _u(rng, -4, 4)) - root_x, _u(rng, -10, 10), _u(rng, -12, 3))
        A.side(side, "Leg", _u(rng, 20, 95))
        A.side(side, "Foot", _u(rng, -10, 20))
    _spine(rng, A, -4, 4)
    _head(rng, A, 0, 20)
    _arms(rng, A, str(rng.choice(["thighs", "armrests", "hanging"])))
    return A.a


def _crossed(rng) -> np.ndarray:
    A = _Angles()
    root_x = _u(rng, -12, 5)
    A.set("Hips", root_x)
    over, under = ("Right", "Left") if rng.random() < 0.5 else ("Left", "Right")
    if rng.random() < 0.5:  # knee over knee (crossed-legs-knees)
        A.side(over, "UpLeg", -_u(rng, 95, 108) - root_x, _u(rng, -5, 5), _u(rng, 20, 30))
        A.side(over, "Leg", _u(rng, 75, 95))
        A.side(over, "Foot", _u(rng, 0, 25))
        _legs_seated(rng, A, under, _u(rng, 85, 95), root_x)
    else:  # legs stretched, ankle over ankle (crossed-legs-ankles)
        A.side(over, "UpLeg", -_u(rng, 84, 92) - root_x, _u(rng, -5, 5), _u(rng, 18, 28))
        A.side(over, "Leg", _u(rng, 45, 65))
        A.side(over, "Foot", _u(rng, 5, 25))
        A.side(under, "UpLeg", -_u(rng, 82, 90) - root_x, _u(rng, -5, 5), _u(rng, 0, 6))
        A.side(under, "Leg", _u(rng, 50, 70))
        A.side(under, "Foot", _u(rng, 5, 25))
    _spine(rng, A, -4, 6)
    _head(rng, A, -10, 15)
    _arms(rng, A, str(rng.choice(["thighs", "armrests", "lap"])))
    return A.a


def _leaning_forward(rng) -> np.ndarray:
    A = _Angles()
    root_x = _u(rng, 15, 30)
    A.set("Hips", root_x)
    elev = _u(rng, -5, 8)
    for side in ("Right", "Left"):
        A.side(side, "UpLeg", -(90 + elev + _u(rng, -4, 4)) - root_x, _u(rng, -10, 10), _u(rng, -15, 0))
        A.side(side, "Leg", _u(rng, 70, 110))
        A.side(side, "Foot", _u(rng, -10, 20))
    _spine(rng, A, 4, 9)
    _head(rng, A, -25, -5)
    # the trunk's pitch from upright (root and spine flexion), deg
    pitch = A.a[SEGMENT_INDEX["Hips"], 0] + sum(A.a[SEGMENT_INDEX[s], 0] for s in ("Spine", "Spine1", "Spine2", "Spine3"))
    for side in ("Right", "Left"):  # elbows on the knees or hands on the thighs
        if rng.random() < 0.6:
            A.side(side, "Arm", _u(rng, -62, -54), 0.0, _u(rng, 84, 88))
            A.side(side, "ForeArm", 0.0, _u(rng, 75, 88), _u(rng, 12, 20))
        else:
            # hands on the thighs: the upper arm 40-60 deg behind the vertical
            # in the world (set against the trunk's pitch, as the thighs are
            # against the root's), so it lies along the flank and the elbow,
            # bent 105-130 deg, lays the forearm along the thigh; the hand
            # ends between the hip and the knee, on the thigh
            A.side(side, "Arm", _u(rng, 40, 60) - pitch, 0.0, _u(rng, 80, 88))
            A.side(side, "ForeArm", 0.0, _u(rng, 105, 130), _u(rng, 0, 15))
    return A.a


def _sideways(rng) -> np.ndarray:
    """Sitting across the seat: both thighs turned 60-90 deg to one side of the trunk."""
    a = _seated(rng)
    turn = _u(rng, 60, 90) * (1 if rng.random() < 0.5 else -1)
    for seg in ("RightUpLeg", "LeftUpLeg"):
        i = SEGMENT_INDEX[seg]
        a[i, 1] = 0.0
        a[i, 2] = 0.0
    # the legs turn about the vertical with the pelvis; the trunk turns back
    a[SEGMENT_INDEX["Hips"], 1] = turn
    a[SEGMENT_INDEX["Spine"], 1] = -turn
    return a


def _fold_legs(rng, a: np.ndarray, hip, abduction, knee, foot) -> None:
    """Both legs folded: hip flexion, abduction, knee and foot angles drawn from the ranges (deg)."""
    for side in ("Right", "Left"):
        sign = 1 if side == "Right" else -1
        a[SEGMENT_INDEX[side + "UpLeg"]] = (-_u(rng, *hip), 0.0, sign * _u(rng, *abduction))
        a[SEGMENT_INDEX[side + "Leg"]] = (_u(rng, *knee), 0.0, 0.0)
        a[SEGMENT_INDEX[side + "Foot"]] = (_u(rng, *foot), 0.0, 0.0)


def _feet_tucked(rng) -> np.ndarray:
    a = _seated(rng)
    _fold_legs(rng, a, (70, 85), (-5, 0), (140, 155), (45, 65))
    return a


def _kneeling(rng) -> np.ndarray:
    """Kneeling upright: thighs near vertical, shanks along the floor behind."""
    a = _seated(rng)
    a[0] = (_u(rng, -5, 5), 0.0, 0.0)
    _fold_legs(rng, a, (0, 20), (-8, 0), (85, 100), (40, 60))
    return a


_DRAW = {
    "seated": _seated,
    "reclined": _reclined,
    "crossed-legs": _crossed,
    "leaning-forward": _leaning_forward,
    "sideways": _sideways,
    "feet-tucked": _feet_tucked,
    "kneeling": _kneeling,
}


def draw_pose(rng: np.random.Generator, family: str, name: str = "") -> DrawnPose:
    """One random pose of ``family`` (one of :data:`FAMILIES` or :data:`UNSUPPORTED_FAMILIES`)."""
    if family not in _DRAW:
        raise ValueError(f"unknown pose family {family!r}; expected one of {', '.join(_DRAW)}")
    angles = _DRAW[family](rng)
    name = name or family
    return DrawnPose(name, family, angles, Pose(euler_to_rotvec(angles), np.zeros(3), name))


def draw_case(case: str, *, seed: int = 2026) -> tuple[DrawnPose, str]:
    """A drawn case ``FAMILY-INDEX@BODY`` (``seated-104@default-male``): pose ``INDEX`` of ``FAMILY`` drawn from the stream ``[seed, INDEX]``, as the benchmarks draw it, and the body's name."""
    name, _, body = case.partition("@")
    family, _, index = name.rpartition("-")
    if not body or not family or not index.isdigit():
        raise ValueError(f"a drawn case is FAMILY-INDEX@BODY (seated-104@default-male), not {case!r}")
    return draw_pose(np.random.default_rng([seed, int(index)]), family, name), body


def draw_poses(n: int, *, seed: int = 0, families=FAMILIES) -> list[DrawnPose]:
    """``n`` random poses, the families in turn (pose ``i`` is of ``families[i % len]``), reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    families = tuple(families)
    out = []
    for i in range(n):
        fam = families[i % len(families)]
        out.append(draw_pose(rng, fam, f"{fam}-{i:03d}"))
    return out


def yaml_float(value: float) -> str:
    """``value`` as a YAML float that reads back as the very same float.

    ``repr`` gives the shortest decimal that round-trips; YAML 1.1 (PyYAML)
    reads a float only with a point in the mantissa and a signed exponent,
    so ``1e-05`` is written ``1.0e-05``.
    """
    text = repr(float(value))
    if "e" in text:
        mantissa, exponent = text.split("e")
        if "." not in mantissa:
            mantissa += ".0"
        text = f"{mantissa}e{exponent if exponent[0] in '+-' else '+' + exponent}"
    elif "." not in text:  # inf, nan: never drawn
        raise ValueError(f"not a finite angle: {value!r}")
    return text


def pose_yaml(drawn: DrawnPose) -> str:
    """The pose as a pose YAML file (docs/poses.md), to reproduce or inspect it.

    Every angle is written at full precision (:func:`yaml_float`): the file
    read back (:func:`seatkit.body.load_pose`) is the drawn pose, bit for
    bit, so a build from the file fits what a fit of ``drawn.pose`` fits.
    """
    lines = [f"description: random {drawn.family} pose {drawn.name} (seatkit.body.generator)", "joints:"]
    for i, seg in enumerate(SEGMENTS[1:], start=1):
        x, y, z = (float(v) for v in drawn.angles[i])
        if x or y or z:
            lines.append(f"  {seg}: {{x: {yaml_float(x)}, y: {yaml_float(y)}, z: {yaml_float(z)}}}")
    x, y, z = (yaml_float(v) for v in drawn.angles[0])
    lines += ["root:", f"  rotation: {{x: {x}, y: {y}, z: {z}}}"]
    return "\n".join(lines) + "\n"
