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
    ``upright-sitting``: the floor to the underside of the thigh just behind
    the knee: the lowest UpLeg vertex 3-10 cm behind the knee joint (the
    higher of the two legs).
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

__all__ = ["MEASUREMENTS", "Measurements", "measure_rig", "enclosed_volume", "print_measurements"]

#: Measurement names, in table order, with their units as printed.
MEASUREMENTS: tuple[str, ...] = (
    "stature",
    "mass",
    "sitting_height",
    "hip_breadth_sitting",
    "buttock_knee_length",
    "popliteal_height",
    "waist_circumference",
    "hip_circumference",
    "volume",
)

#: Hip breadth is taken over the hips and thighs up to this far ahead of the
#: hip joint centre (m): the survey's subject sits with the knees together,
#: the library pose has them hip-width apart, so the far thighs would count.
HIP_BREADTH_REACH = 0.15

_HIP_THIGH = ("Hips", "RightUpLeg", "LeftUpLeg")
_THIGH_SHANK = ("RightUpLeg", "LeftUpLeg", "RightLeg", "LeftLeg")
_TRUNK = ("Hips", "Spine", "Spine1", "Spine2", "Spine3")


@dataclass(frozen=True)
class Measurements:
    """A body's survey measurements (m, kg, m^3)."""

    stature: float
    mass: float
    sitting_height: float
    hip_breadth_sitting: float
    buttock_knee_length: float
    popliteal_height: float
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


def measure_bodies(standing: Body, sitting: Body, rest_volume: float) -> Measurements:
    """The measurements from a body posed ``standing`` and ``upright-sitting`` (both grounded)."""
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
    buttock_knee = float(sv[thigh_shank, 2].max() - sv[hip_thigh, 2].min())
    popliteal = 0.0
    for side in ("Right", "Left"):
        knee_z = sitting.joints[SEGMENT_INDEX[f"{side}Leg"]][2]
        thigh = _dominant(w, (f"{side}UpLeg",)) & (sv[:, 2] > knee_z - 0.10) & (sv[:, 2] < knee_z - 0.03)
        popliteal = max(popliteal, float(sv[thigh, 1].min()) if thigh.any() else 0.0)
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
        waist_circumference=waist,
        hip_circumference=hips,
        volume=rest_volume,
    )


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
    return measure_bodies(standing, sitting, enclosed_volume(rig.vertices, rig.faces))


def print_measurements(rig: RiggedBody) -> Measurements:
    """Measure ``rig`` and print one line per measurement (and the density check) on stdout."""
    import click

    from seatkit.body.anthropometry import body_density

    m = measure_rig(rig)
    density = body_density(m.stature, m.mass)
    click.echo(f"{rig.name}: measured on the mesh (docs/bodies.md, 'Measuring a body')")
    for key, value in m.as_dict().items():
        unit = "kg" if key == "mass" else "m^3" if key == "volume" else "m"
        click.echo(f"  {key:22s} {value:9.4f} {unit}")
    click.echo(f"  {'bmi':22s} {m.mass / m.stature**2:9.2f} kg/m^2")
    click.echo(f"  volume x density       {m.volume * density:9.2f} kg (Contini 1972: {density:.0f} kg/m^3)")
    return m
