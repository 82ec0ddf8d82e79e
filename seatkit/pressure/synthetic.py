"""A synthetic seated body of capsules, for tests and benchmarks.

Each of the 21 segments is a closed capsule from its proximal joint to its
tip; vertices near a proximal joint blend their skinning weight with the
parent segment (linearly over the capsule radius), so reactions are shared
between segments as on a real skinned body. The skeleton sits upright on a
seat of height :data:`SEAT_HEIGHT` (thighs horizontal, shanks vertical, feet
on the floor at y = 0, trunk reclined by about 15 degrees, forearms forward).
Masses are Plagenhoef-like fractions of :data:`seatkit.constants.DEFAULT_BODY_MASS`.
It needs no data files, so tests run before (and without) the real bodies.
"""

from __future__ import annotations

import numpy as np

from seatkit.constants import DEFAULT_BODY_MASS
from seatkit.model import Body
from seatkit.skeleton import N_SEGMENTS, PARENTS

__all__ = ["SEAT_HEIGHT", "BACKREST_Z", "seated_capsule_body", "capsule"]

#: Height of the seat plane under the synthetic body's buttocks and thighs, m.
SEAT_HEIGHT = 0.43

#: The backrest plane passes through (0, 0.75, BACKREST_Z) tilted 15 degrees back.
BACKREST_Z = -0.18

# joint, tip, radius, mass fraction (before normalisation) per segment
_R, _L = -1.0, 1.0
_SEGMENTS = [
    ((0.0, 0.55, -0.03), (0.0, 0.65, -0.06), 0.12, 14.0),  # Hips
    ((-0.09, 0.50, 0.0), (-0.09, 0.50, 0.42), 0.07, 10.5),  # RightUpLeg
    ((-0.09, 0.50, 0.42), (-0.09, 0.09, 0.44), 0.05, 4.75),  # RightLeg
    ((-0.09, 0.09, 0.44), (-0.09, 0.04, 0.60), 0.04, 1.43),  # RightFoot
    ((0.09, 0.50, 0.0), (0.09, 0.50, 0.42), 0.07, 10.5),  # LeftUpLeg
    ((0.09, 0.50, 0.42), (0.09, 0.09, 0.44), 0.05, 4.75),  # LeftLeg
    ((0.09, 0.09, 0.44), (0.09, 0.04, 0.60), 0.04, 1.43),  # LeftFoot
    ((0.0, 0.65, -0.06), (0.0, 0.75, -0.09), 0.13, 8.0),  # Spine
    ((0.0, 0.75, -0.09), (0.0, 0.85, -0.12), 0.13, 8.0),  # Spine1
    ((0.0, 0.85, -0.12), (0.0, 0.95, -0.15), 0.14, 9.0),  # Spine2
    ((0.0, 0.95, -0.15), (0.0, 1.06, -0.18), 0.15, 10.1),  # Spine3
    ((0.0, 1.06, -0.18), (0.0, 1.14, -0.19), 0.05, 1.26),  # Neck
    ((0.0, 1.14, -0.19), (0.0, 1.34, -0.20), 0.10, 7.0),  # Head
    ((-0.03, 1.03, -0.17), (-0.19, 1.03, -0.17), 0.05, 1.0),  # RightShoulder
    ((-0.19, 1.03, -0.17), (-0.21, 0.76, -0.12), 0.045, 3.25),  # RightArm
    ((-0.21, 0.76, -0.12), (-0.19, 0.70, 0.14), 0.04, 1.87),  # RightForeArm
    ((-0.19, 0.70, 0.14), (-0.18, 0.68, 0.28), 0.03, 0.65),  # RightHand
    ((0.03, 1.03, -0.17), (0.19, 1.03, -0.17), 0.05, 1.0),  # LeftShoulder
    ((0.19, 1.03, -0.17), (0.21, 0.76, -0.12), 0.045, 3.25),  # LeftArm
    ((0.21, 0.76, -0.12), (0.19, 0.70, 0.14), 0.04, 1.87),  # LeftForeArm
    ((0.19, 0.70, 0.14), (0.18, 0.68, 0.28), 0.03, 0.65),  # LeftHand
]


def capsule(a, b, radius: float, *, sectors: int = 24, rings: int = 8, stacks: int = 6):
    """Closed capsule mesh from ``a`` to ``b`` (outward, counter-clockwise).

    Returns
    -------
    vertices : (p, 3) float64
    faces : (q, 3) int64
    along : (p,) float64
        Signed distance of each vertex from ``a`` along the axis, m.
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    ez = axis / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(ez[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    ex = np.cross(helper, ez)
    ex /= np.linalg.norm(ex)
    ey = np.cross(ez, ex)
    # profile: (axial offset, radial distance) from the bottom pole to the top pole
    th_lo = np.linspace(-np.pi / 2, 0, rings + 1)[1:]
    th_hi = np.linspace(0, np.pi / 2, rings + 1)[:-1]
    prof = [(radius * np.sin(t), radius * np.cos(t)) for t in th_lo]
    prof += [(length * s, radius) for s in np.linspace(0, 1, stacks + 1)[1:-1]]
    prof += [(length + radius * np.sin(t), radius * np.cos(t)) for t in th_hi]
    prof = np.array(prof)
    phi = np.linspace(0, 2 * np.pi, sectors, endpoint=False)
    ring_pts = (
        prof[:, 0, None, None] * ez
        + prof[:, 1, None, None] * (np.cos(phi)[None, :, None] * ex + np.sin(phi)[None, :, None] * ey)
    ).reshape(-1, 3)
    bottom = -radius * ez
    top = (length + radius) * ez
    verts = np.vstack([bottom, ring_pts, top]) + a
    along = np.concatenate([[-radius], np.repeat(prof[:, 0], sectors), [length + radius]])
    nr = len(prof)
    idx = 1 + np.arange(nr * sectors).reshape(nr, sectors)
    nxt = np.roll(idx, -1, axis=1)
    faces = [np.stack([np.zeros(sectors, int), nxt[0], idx[0]], axis=1)]
    q00, q01, q10, q11 = idx[:-1], nxt[:-1], idx[1:], nxt[1:]
    faces.append(np.stack([q00, q01, q11], axis=-1).reshape(-1, 3))
    faces.append(np.stack([q00, q11, q10], axis=-1).reshape(-1, 3))
    top_i = 1 + nr * sectors
    faces.append(np.stack([np.full(sectors, top_i), idx[-1], nxt[-1]], axis=1))
    return verts, np.concatenate(faces).astype(np.int64), along


def seated_capsule_body(*, resolution: int = 1, mass: float = DEFAULT_BODY_MASS) -> Body:
    """The synthetic seated body.

    Parameters
    ----------
    resolution : int
        1 gives about 3,600 vertices; the vertex count grows as its square
        (4 gives about 13,000, the size of the default body).
    mass : float
        Body mass, kg.

    Returns
    -------
    Body
    """
    verts, faces, weights = [], [], []
    offset = 0
    joints = np.zeros((N_SEGMENTS, 3))
    tips = np.zeros((N_SEGMENTS, 3))
    for s, (a, b, radius, _) in enumerate(_SEGMENTS):
        v, f, along = capsule(a, b, radius, sectors=12 * resolution, rings=4 * resolution, stacks=3 * resolution)
        w = np.zeros((len(v), N_SEGMENTS))
        w[:, s] = 1.0
        if PARENTS[s] >= 0:
            # blend with the parent near the proximal joint
            share = 0.5 * np.clip(1.0 - (along + radius) / (2.0 * radius), 0.0, 1.0)
            w[:, s] -= share
            w[:, PARENTS[s]] += share
        verts.append(v)
        faces.append(f + offset)
        weights.append(w)
        offset += len(v)
        joints[s], tips[s] = a, b
    frac = np.array([seg[3] for seg in _SEGMENTS])
    segment_mass = mass * frac / frac.sum()
    return Body(
        vertices=np.vstack(verts),
        faces=np.vstack(faces),
        weights=np.vstack(weights),
        joints=joints,
        tips=tips,
        segment_mass=segment_mass,
        segment_com=0.5 * (joints + tips),
        name="synthetic-seated",
        region_labels={},
    )
