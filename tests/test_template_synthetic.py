"""A synthetic capsule body for template tests, and the tests of that body.

Each of the 21 segments is an ellipsoidal capsule around its bone, skinned
rigidly (one-hot weights). It lets template tests run without the shipped
bodies and the pressure solver: :func:`standin_pressure` is a documented
stand-in importance (downward-facing area, plus a little on backward-facing
skin), for tests and development only; shipped code takes the importance
from the real :class:`seatkit.model.PressureField`.
"""

from __future__ import annotations

import numpy as np
import trimesh

from seatkit.model import Body, PressureField
from seatkit.skeleton import N_SEGMENTS, SEGMENT_INDEX

# Radii (m) of each segment's capsule: (across, front-back) half-widths.
_RADII = {
    "Hips": (0.17, 0.12), "RightUpLeg": (0.075, 0.075), "RightLeg": (0.055, 0.055), "RightFoot": (0.045, 0.035),
    "LeftUpLeg": (0.075, 0.075), "LeftLeg": (0.055, 0.055), "LeftFoot": (0.045, 0.035),
    "Spine": (0.15, 0.10), "Spine1": (0.15, 0.10), "Spine2": (0.16, 0.10), "Spine3": (0.17, 0.10),
    "Neck": (0.05, 0.05), "Head": (0.08, 0.09),
    "RightShoulder": (0.05, 0.05), "RightArm": (0.045, 0.045), "RightForeArm": (0.04, 0.04), "RightHand": (0.03, 0.02),
    "LeftShoulder": (0.05, 0.05), "LeftArm": (0.045, 0.045), "LeftForeArm": (0.04, 0.04), "LeftHand": (0.03, 0.02),
}


def seated_skeleton(*, knee_gap: float = 0.10, lean: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Joints and tips (21, 3) of a person sitting upright, facing +Z.

    ``knee_gap`` is the distance between the knees (m); ``lean`` tilts the
    torso forward (radians, positive = towards +Z).
    """
    j = np.zeros((N_SEGMENTS, 3))
    t = np.zeros((N_SEGMENTS, 3))
    s = SEGMENT_INDEX
    hip = np.array([0.0, 0.55, 0.0])
    j[s["Hips"]] = hip
    for side, sx in (("Right", -1.0), ("Left", 1.0)):
        hx = sx * 0.09
        kx = sx * (knee_gap / 2 + 0.05)
        j[s[side + "UpLeg"]] = hip + [hx, -0.02, 0.03]
        t[s[side + "UpLeg"]] = j[s[side + "Leg"]] = [kx, 0.52, 0.47]
        t[s[side + "Leg"]] = j[s[side + "Foot"]] = [kx, 0.09, 0.44]
        t[s[side + "Foot"]] = [kx * 1.05, 0.035, 0.66]
    # torso: a chain of points above the hips, tilted by ``lean`` about X
    heights = [0.10, 0.21, 0.31, 0.41, 0.53, 0.61, 0.83]
    c, sn = np.cos(lean), np.sin(lean)
    chain = [hip + [0.0, h * c, -0.04 + h * sn] for h in heights]
    names = ["Hips", "Spine", "Spine1", "Spine2", "Spine3", "Neck", "Head"]
    t[s["Hips"]] = chain[0]
    for k, name in enumerate(names[1:], start=1):
        j[s[name]] = chain[k - 1]
        t[s[name]] = chain[k]
    top = chain[3]
    for side, sx in (("Right", -1.0), ("Left", 1.0)):
        j[s[side + "Shoulder"]] = top
        t[s[side + "Shoulder"]] = j[s[side + "Arm"]] = top + [sx * 0.19, 0.05, 0.0]
        t[s[side + "Arm"]] = j[s[side + "ForeArm"]] = top + [sx * 0.21, -0.24, 0.02]
        t[s[side + "ForeArm"]] = j[s[side + "Hand"]] = top + [sx * 0.21, -0.26, 0.27]
        t[s[side + "Hand"]] = top + [sx * 0.21, -0.28, 0.36]
    return j, t


def capsule_body(joints: np.ndarray, tips: np.ndarray, *, ground: bool = True, name: str = "capsules") -> Body:
    """A body made of one ellipsoidal capsule per segment.

    Returns
    -------
    Body
        Vertices of every capsule, one-hot skinning weights.
    """
    verts, faces, weights = [], [], []
    offset = 0
    for seg in range(N_SEGMENTS):
        a, b = joints[seg], tips[seg]
        axis = b - a
        length = float(np.linalg.norm(axis))
        rx, rz = _RADII[[k for k, v in SEGMENT_INDEX.items() if v == seg][0]]
        mesh = trimesh.creation.capsule(height=max(length, 1e-3), radius=1.0, count=[24, 12])
        v = mesh.vertices.copy()
        # unit capsule along z from -h/2..h/2 with radius 1: scale the cross-section
        v[:, 0] *= rx
        v[:, 1] *= rz
        # the capsule is centred, z in [-(L/2 + 1), L/2 + 1]: keep the cylinder, flatten the caps
        z = v[:, 2]
        cap = np.sign(z) * np.maximum(np.abs(z) - length / 2, 0.0)
        v[:, 2] = np.clip(z, -length / 2, length / 2) + cap * min(rx, rz)
        # frame: z along the bone, x across the body (world X projected), y = z cross x
        ez = axis / max(length, 1e-9)
        ref = np.array([1.0, 0.0, 0.0]) if abs(ez[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        ex = ref - ez * (ref @ ez)
        ex /= np.linalg.norm(ex)
        ey = np.cross(ez, ex)
        rot = np.stack([ex, ey, ez], axis=1)
        v = v @ rot.T + (a + b) / 2
        verts.append(v)
        faces.append(mesh.faces + offset)
        w = np.zeros((len(v), N_SEGMENTS))
        w[:, seg] = 1.0
        weights.append(w)
        offset += len(v)
    vertices = np.concatenate(verts)
    shift = np.zeros(3)
    if ground:
        shift[1] = -vertices[:, 1].min()
    com = (joints + tips) / 2 + shift
    mass = np.full(N_SEGMENTS, 75.0 / N_SEGMENTS)
    return Body(vertices + shift, np.concatenate(faces).astype(np.int64), np.concatenate(weights), joints + shift, tips + shift, mass, com, name=name)


def standin_pressure(body: Body, *, back_share: float = 0.3) -> PressureField:
    """Stand-in importance: downward-facing area plus some on backward skin.

    For tests and development only: pressure (Pa) is 3000 times the downward
    component of the vertex normal, plus ``back_share`` times that on
    backward-facing vertices of the torso.
    """
    mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
    n = mesh.vertex_normals
    area = np.zeros(len(body.vertices))
    np.add.at(area, body.faces.ravel(), np.repeat(mesh.area_faces / 3, 3))
    seg = body.weights.argmax(1)
    torso = np.isin(seg, [SEGMENT_INDEX[k] for k in ("Spine", "Spine1", "Spine2", "Spine3")])
    down = np.clip(-n[:, 1], 0, None)
    # only the lowest skin of legs and pelvis carries load
    low = body.vertices[:, 1] < np.percentile(body.vertices[:, 1], 45)
    pressure = 3000.0 * down * (low | (seg == SEGMENT_INDEX["Hips"]))
    pressure += 3000.0 * back_share * np.clip(-n[:, 2], 0, None) * torso
    normal_force = pressure * area
    force = normal_force[:, None] * np.array([0.0, 1.0, 0.0])
    nj = N_SEGMENTS - 1
    return PressureField(force, normal_force, pressure, np.zeros_like(pressure), area, np.ones(len(area), bool), np.zeros((nj, 3)), np.zeros((nj, 3)))


def seated_capsules(**kwargs) -> tuple[Body, PressureField]:
    """A seated capsule body and its stand-in pressure."""
    body = capsule_body(*seated_skeleton(**kwargs))
    return body, standin_pressure(body)


def test_capsule_body_is_grounded_and_skinned():
    body, pressure = seated_capsules()
    assert body.vertices[:, 1].min() == 0.0
    np.testing.assert_allclose(body.weights.sum(1), 1.0)
    assert body.faces.max() < len(body.vertices)
    # the stand-in loads the underside of thighs and buttocks most
    seg = body.weights.argmax(1)
    thigh = np.isin(seg, [SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]])
    assert pressure.normal_force[thigh].sum() > 0.2 * pressure.normal_force.sum()
