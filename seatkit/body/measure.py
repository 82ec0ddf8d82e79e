"""Measuring a body on its mesh, the way an anthropometric survey measures a person.

The procedure (``docs/bodies.md``, "Measuring a body") poses the rig in two
library poses and reads distances off the skinned mesh. Names and
definitions follow the ANSUR II survey (Gordon et al. 2014) as closely as a
mesh allows:

``stature``
    ``standing`` pose, grounded: top of the head above the floor (the soles
    are on y = 0).
``sitting_height``
    ``upright-sitting`` pose (thighs level, knees at 90 degrees, trunk
    erect): top of the head above the sitting surface, the lowest point of
    the buttocks and thighs (vertices whose largest weight is Hips or UpLeg).
``hip_breadth_sitting``
    ``upright-sitting``: the largest side-to-side (x) extent of the hips and
    thighs (Hips and UpLeg vertices; hands lying on the thighs do not count)
    up to 15 cm ahead of the hip joint centre (the survey's subject has the
    knees together; the pose has them hip-width apart).
``buttock_knee_length``
    ``upright-sitting``: from the rearmost point of the buttocks (Hips and
    UpLeg vertices) to the front of the kneecaps (UpLeg and Leg vertices),
    along the body's forward axis (+z).
``popliteal_height``
    ``upright-sitting`` (thighs level, knees at 90 degrees, feet flat):
    ANSUR II's footrest surface (the floor under the bare feet) to the
    underside of the thigh just behind the knee: the lowest UpLeg vertex 3-10
    cm behind the knee joint (the higher of the two legs).
``knee_height_sitting``
    ``upright-sitting``: the floor to the top of the knee (ANSUR II's
    suprapatella, the top of the kneecap): the highest thigh or shank (UpLeg,
    Leg) vertex from 3 cm behind to 6 cm ahead of the knee joint (the higher
    of the two legs).
``buttock_popliteal_length``
    ``upright-sitting``: along the forward axis, from the rearmost point of
    the buttocks (as for buttock-knee length) to the back of the knee (ANSUR
    II's popliteal fossa, where the calf meets the thigh): the rearmost
    shank (Leg) vertex within 1.5 cm of the knee joint's side-to-side
    position (the middle of the knee, where the anthropometer's blade
    touches) and from the thigh's underside (popliteal height) to 2 cm below
    it (the shorter of the two legs).
``thigh_clearance``
    ``upright-sitting``: the sitting surface (the lowest point of the
    buttocks and thighs, as for sitting height) to the highest point on top
    of the thigh (UpLeg vertices; the hands resting on them do not count)
    (the higher of the two legs).
``elbow_rest_height``
    ``elbow-rest`` (``upright-sitting`` with the upper arms hanging straight
    down and the elbows bent 90 degrees, forearms level and forward, as ANSUR
    II measures it): the sitting surface to the bottom of the elbow, the
    lowest upper-arm or forearm (Arm, ForeArm) vertex within 6 cm of the
    elbow joint (the lower of the two arms).
``waist_circumference``
    ``standing``: the length of a tape around the trunk at the height of the
    ``Spine1`` joint (the lumbar joint between the two abdominal segments, at
    about the navel): the convex hull of the horizontal section of the trunk
    (faces of Hips and Spine..Spine3 vertices, so the hanging arms do not
    count).
``hip_circumference``
    ``standing``: the largest tape length around the hips and buttocks
    (Hips and UpLeg faces) over horizontal sections from 15 cm below to 5 cm
    above the hip joint centre, every 5 mm (ANSUR's buttock circumference is
    taken at the level of the buttocks' greatest protrusion).
``volume``
    The signed volume enclosed by the rest mesh (the skin is closed), m^3.

All lengths in metres. Survey measurements are on a lightly clothed person
pressed by a tape or an anthropometer; the mesh is bare skin without soft
tissue compression, so a few millimetres of difference are expected.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import ConvexHull

from seatkit.model import Body, RiggedBody
from seatkit.skeleton import SEGMENT_INDEX

__all__ = ["MEASUREMENTS", "HOW_MEASURED", "Measurements", "measure_rig", "enclosed_volume", "print_measurements"]

#: Measurement names, in table order, with their units as printed.
MEASUREMENTS: tuple[str, ...] = (
    "stature",
    "mass",
    "sitting_height",
    "hip_breadth_sitting",
    "buttock_knee_length",
    "popliteal_height",
    "knee_height_sitting",
    "buttock_popliteal_length",
    "thigh_clearance",
    "elbow_rest_height",
    "waist_circumference",
    "hip_circumference",
    "volume",
)

#: How each measurement is taken, one line each (``seatkit body --measure`` prints them): the posture,
#: the landmarks, and the ANSUR II measurement it follows (Gordon et al. 2014; the module docstring
#: says more).
HOW_MEASURED: dict[str, str] = {
    "stature": "standing: floor to the top of the head (ANSUR II stature)",
    "mass": "the body mass asked for (ANSUR II weightkg for a preset)",
    "sitting_height": "upright-sitting: sitting surface (lowest buttock/thigh point) to the top of the head (ANSUR II sittingheight)",
    "hip_breadth_sitting": "upright-sitting: widest hips/thighs up to 15 cm ahead of the hip joints (ANSUR II hipbreadthsitting)",
    "buttock_knee_length": "upright-sitting: rearmost buttock to the front of the knee, horizontally (ANSUR II buttockkneelength)",
    "popliteal_height": "upright-sitting, thighs level, knees at 90 deg, bare feet flat: floor to the underside of the thigh "
    "3-10 cm behind the knee joint (ANSUR II poplitealheight)",
    "knee_height_sitting": "upright-sitting: floor to the top of the knee (suprapatella), the highest thigh/shank point "
    "from 3 cm behind to 6 cm ahead of the knee joint (ANSUR II kneeheightsitting)",
    "buttock_popliteal_length": "upright-sitting: rearmost buttock to the back of the knee (popliteal fossa), the rearmost "
    "calf point in the knee's mid-plane within 2 cm under the thigh, horizontally (ANSUR II buttockpopliteallength)",
    "thigh_clearance": "upright-sitting: sitting surface to the highest point on top of the thigh (ANSUR II thighclearance)",
    "elbow_rest_height": "upright-sitting, upper arms hanging, elbows at 90 deg, forearms level: sitting surface to the "
    "bottom of the elbow (ANSUR II elbowrestheight)",
    "waist_circumference": "standing: tape (convex hull) around the trunk at the Spine1 joint (ANSUR II waistcircumference)",
    "hip_circumference": "standing: largest tape around hips and buttocks, 15 cm below to 5 cm above the hip joints "
    "(ANSUR II buttockcircumference)",
    "volume": "volume enclosed by the rest mesh",
}

#: Hip breadth is taken over the hips and thighs up to this far ahead of the
#: hip joint centre (m): the survey's subject sits with the knees together,
#: the library pose has them hip-width apart, so the far thighs would count.
HIP_BREADTH_REACH = 0.15

_HIP_THIGH = ("Hips", "RightUpLeg", "LeftUpLeg")
_THIGH_SHANK = ("RightUpLeg", "LeftUpLeg", "RightLeg", "LeftLeg")
_TRUNK = ("Hips", "Spine", "Spine1", "Spine2", "Spine3")
#: The knee's top (suprapatella) is sought from this far behind to this far ahead of the knee joint, m.
KNEE_TOP_BAND = (0.03, 0.06)
#: The back of the knee (popliteal fossa) is sought this far below the thigh's underside, m, and
#: this close to the knee joint side to side.
POPLITEAL_FOSSA_BAND = 0.02
POPLITEAL_FOSSA_HALF_WIDTH = 0.015
#: The bottom of the elbow is sought this close to the elbow joint, m.
ELBOW_REACH = 0.06
#: The elbow-rest posture: upper arms hanging, elbows at 90 degrees, forearms level and forward
#: (intrinsic XYZ Euler angles, degrees, on top of ``upright-sitting``).
ELBOW_REST_ARMS = {
    "RightArm": (0.0, 0.0, 90.0),
    "LeftArm": (0.0, 0.0, -90.0),
    "RightForeArm": (0.0, 90.0, 0.0),
    "LeftForeArm": (0.0, -90.0, 0.0),
    "RightHand": (0.0, 0.0, 0.0),
    "LeftHand": (0.0, 0.0, 0.0),
}


@dataclass(frozen=True)
class Measurements:
    """A body's survey measurements (m, kg, m^3)."""

    stature: float
    mass: float
    sitting_height: float
    hip_breadth_sitting: float
    buttock_knee_length: float
    popliteal_height: float
    knee_height_sitting: float
    buttock_popliteal_length: float
    thigh_clearance: float
    elbow_rest_height: float
    waist_circumference: float
    hip_circumference: float
    volume: float

    def as_dict(self) -> dict:
        return asdict(self)


def enclosed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume enclosed by a closed, outward-oriented triangle mesh, m^3.

    The sum of ``a . (b x c) / 6`` over the triangles, on coordinate columns
    (a few times faster than on (m, 3) rows: the parametric body calls it in
    its mass loop).
    """
    x, y, z = (np.ascontiguousarray(vertices[:, k]) for k in range(3))
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    ax, ay, az = x[f0], y[f0], z[f0]
    bx, by, bz = x[f1], y[f1], z[f1]
    cx, cy, cz = x[f2], y[f2], z[f2]
    return float((ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)).sum() / 6.0)


def _dominant(weights: np.ndarray, names) -> np.ndarray:
    """Vertices whose largest skinning weight is one of the segments ``names``."""
    return np.isin(np.argmax(weights, axis=1), [SEGMENT_INDEX[n] for n in names])


def _section_girth(vertices: np.ndarray, faces: np.ndarray, y: float) -> float:
    """Tape length around the horizontal section of a mesh at height ``y``.

    The section of every triangle crossing the plane is intersected exactly;
    the tape is the convex hull of the section points (a tape bridges the
    hollows between buttocks or thighs). 0 if the plane misses the mesh.
    """
    h = vertices[faces, 1] - y  # (m, 3) heights above the plane
    crossing = (h.min(axis=1) < 0.0) & (h.max(axis=1) > 0.0)
    if not crossing.any():
        return 0.0
    tri = vertices[faces[crossing]]
    hc = h[crossing]
    points = []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        hi, hj = hc[:, i], hc[:, j]
        cut = (hi < 0.0) != (hj < 0.0)
        t = hi[cut] / (hi[cut] - hj[cut])
        p = tri[cut, i] + t[:, None] * (tri[cut, j] - tri[cut, i])
        points.append(p[:, [0, 2]])
    pts = np.concatenate(points)
    if len(pts) < 3:
        return 0.0
    return float(ConvexHull(pts).area)  # in 2-D, "area" is the perimeter


def _sub_faces(faces: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return faces[mask[faces].all(axis=1)]


def measure_bodies(standing: Body, sitting: Body, rest_volume: float, elbow_rest: Body | None = None) -> Measurements:
    """The measurements from a body posed ``standing``, ``upright-sitting`` and ``elbow-rest`` (all grounded).

    ``elbow_rest`` defaults to ``sitting`` (the elbow rest height is then
    read off whatever the arms do in that pose).
    """
    elbow_rest = sitting if elbow_rest is None else elbow_rest
    w = standing.weights
    hip_thigh = _dominant(w, _HIP_THIGH)
    thigh_shank = _dominant(w, _THIGH_SHANK)
    trunk = _dominant(w, _TRUNK)
    stature = float(standing.vertices[:, 1].max() - standing.vertices[:, 1].min())
    sv = sitting.vertices
    seat = float(sv[hip_thigh, 1].min())
    sitting_height = float(sv[:, 1].max() - seat)
    near_hips = hip_thigh & (sv[:, 2] < sitting.joints[SEGMENT_INDEX["Hips"]][2] + HIP_BREADTH_REACH)
    hip_breadth = float(np.ptp(sv[near_hips, 0]))
    buttock = float(sv[hip_thigh, 2].min())
    buttock_knee = float(sv[thigh_shank, 2].max() - buttock)
    popliteal, knee_top, thigh_top, fossa = 0.0, 0.0, 0.0, np.inf
    for side in ("Right", "Left"):
        knee_z = sitting.joints[SEGMENT_INDEX[f"{side}Leg"]][2]
        up = _dominant(w, (f"{side}UpLeg",))
        thigh = up & (sv[:, 2] > knee_z - 0.10) & (sv[:, 2] < knee_z - 0.03)
        under = float(sv[thigh, 1].min()) if thigh.any() else 0.0
        popliteal = max(popliteal, under)
        knee = _dominant(w, (f"{side}UpLeg", f"{side}Leg"))
        knee &= (sv[:, 2] > knee_z - KNEE_TOP_BAND[0]) & (sv[:, 2] < knee_z + KNEE_TOP_BAND[1])
        knee_top = max(knee_top, float(sv[knee, 1].max()) if knee.any() else 0.0)
        thigh_top = max(thigh_top, float(sv[up, 1].max()) - seat)
        knee_x = sitting.joints[SEGMENT_INDEX[f"{side}Leg"]][0]
        calf = _dominant(w, (f"{side}Leg",)) & (sv[:, 1] <= under) & (sv[:, 1] >= under - POPLITEAL_FOSSA_BAND)
        calf &= np.abs(sv[:, 0] - knee_x) < POPLITEAL_FOSSA_HALF_WIDTH
        if calf.any():
            fossa = min(fossa, float(sv[calf, 2].min()) - buttock)
    ev = elbow_rest.vertices
    er_seat = float(ev[hip_thigh, 1].min())
    elbow = np.inf
    for side in ("Right", "Left"):
        joint = elbow_rest.joints[SEGMENT_INDEX[f"{side}ForeArm"]]
        arm = _dominant(w, (f"{side}Arm", f"{side}ForeArm")) & (np.linalg.norm(ev - joint, axis=1) < ELBOW_REACH)
        if arm.any():
            elbow = min(elbow, float(ev[arm, 1].min()) - er_seat)
    v = standing.vertices
    waist_y = float(standing.joints[SEGMENT_INDEX["Spine1"]][1])
    waist = _section_girth(v, _sub_faces(standing.faces, trunk), waist_y)
    hip_faces = _sub_faces(standing.faces, hip_thigh)
    hip_y = float(standing.joints[SEGMENT_INDEX["Hips"]][1])
    hips = max(_section_girth(v, hip_faces, y) for y in np.arange(hip_y - 0.15, hip_y + 0.05 + 1e-9, 0.005))
    return Measurements(
        stature=stature,
        mass=float(standing.mass),
        sitting_height=sitting_height,
        hip_breadth_sitting=hip_breadth,
        buttock_knee_length=buttock_knee,
        popliteal_height=popliteal,
        knee_height_sitting=knee_top,
        buttock_popliteal_length=float(fossa) if np.isfinite(fossa) else 0.0,
        thigh_clearance=thigh_top,
        elbow_rest_height=float(elbow) if np.isfinite(elbow) else 0.0,
        waist_circumference=waist,
        hip_circumference=hips,
        volume=rest_volume,
    )


def elbow_rest_pose():
    """``upright-sitting`` with ANSUR II's elbow-rest arms (:data:`ELBOW_REST_ARMS`)."""
    from seatkit.body.poses import euler_to_rotvec, load_pose
    from seatkit.model import Pose

    base = load_pose("upright-sitting")
    rotations = base.rotations.copy()
    for name, angles in ELBOW_REST_ARMS.items():
        rotations[SEGMENT_INDEX[name]] = euler_to_rotvec(np.array([angles]))[0]
    return Pose(rotations, base.translation, name="elbow-rest")


def measure_rig(rig: RiggedBody) -> Measurements:
    """Measure a rigged body by the documented procedure (see the module docstring).

    Parameters
    ----------
    rig : RiggedBody
        In a T-pose rest (as every seatkit rig).

    Returns
    -------
    Measurements
    """
    from seatkit.body.poses import load_pose
    from seatkit.body.skinning import pose_rig

    standing = pose_rig(rig, load_pose("standing"), ground=True)
    sitting = pose_rig(rig, load_pose("upright-sitting"), ground=True)
    elbow = pose_rig(rig, elbow_rest_pose(), ground=True)
    return measure_bodies(standing, sitting, enclosed_volume(rig.vertices, rig.faces), elbow)


def print_measurements(rig: RiggedBody) -> Measurements:
    """Measure ``rig`` and print one line per measurement (and the density check) on stdout."""
    import typer

    from seatkit.body.anthropometry import body_density

    m = measure_rig(rig)
    density = body_density(m.stature, m.mass)
    typer.echo(f"{rig.name}: measured on the bare-skin mesh (docs/bodies.md, 'Measuring a body')")
    for key, value in m.as_dict().items():
        unit = "kg" if key == "mass" else "m^3" if key == "volume" else "m"
        typer.echo(f"  {key:24s} {value:9.4f} {unit:4s} {HOW_MEASURED[key]}")
    typer.echo(f"  {'bmi':24s} {m.mass / m.stature**2:9.2f} kg/m^2")
    typer.echo(f"  {'volume x density':24s} {m.volume * density:9.2f} kg   (Contini 1972: {density:.0f} kg/m^3)")
    return m
