"""Skinned glTF/GLB body import (seatkit.body.gltf), on GLB files written here with pygltflib."""

from __future__ import annotations

import base64

import numpy as np
import pygltflib
import pytest
from scipy.spatial.transform import Rotation

from seatkit.body.gltf import load_gltf_body
from seatkit.body.skinning import pose_rig
from seatkit.errors import InputError
from seatkit.model import Pose
from seatkit.skeleton import N_SEGMENTS, PARENTS, SEGMENTS, SEGMENT_INDEX as I

# MakeHuman / MPFB default-rig names of the 21 segments' proximal joints
MH_NAMES = {
    "Hips": "root", "RightUpLeg": "upperleg01.R", "RightLeg": "lowerleg01.R", "RightFoot": "foot.R",
    "LeftUpLeg": "upperleg01.L", "LeftLeg": "lowerleg01.L", "LeftFoot": "foot.L",
    "Spine": "spine04", "Spine1": "spine03", "Spine2": "spine02", "Spine3": "spine01",
    "Neck": "neck01", "Head": "head", "RightShoulder": "clavicle.R", "RightArm": "upperarm01.R",
    "RightForeArm": "lowerarm01.R", "RightHand": "wrist.R", "LeftShoulder": "clavicle.L",
    "LeftArm": "upperarm01.L", "LeftForeArm": "lowerarm01.L", "LeftHand": "wrist.L",
}
# extra (unmapped) joints: name, parent segment, position relative to the parent's joint
EXTRAS = [("spine05", "Hips", [0, 0.04, 0]), ("upperarm02.L", "LeftArm", [0.14, 0, 0]),
          ("finger2-1.L", "LeftHand", [0.09, 0, 0]), ("toe1-1.R", "RightFoot", [0, -0.05, 0.12])]


def _skeleton():
    j = np.zeros((N_SEGMENTS, 3))
    j[I["Hips"]] = [0, 1.0, 0]
    for side, x in (("Right", -0.09), ("Left", 0.09)):
        j[I[side + "UpLeg"]] = [x, 0.95, 0]
        j[I[side + "Leg"]] = [x, 0.52, 0.01]
        j[I[side + "Foot"]] = [x, 0.08, 0]
    for k, name in enumerate(["Spine", "Spine1", "Spine2", "Spine3"]):
        j[I[name]] = [0, 1.08 + 0.1 * k, 0]
    j[I["Neck"]] = [0, 1.50, 0]
    j[I["Head"]] = [0, 1.58, 0]
    for side, sg in (("Right", -1), ("Left", 1)):
        j[I[side + "Shoulder"]] = [sg * 0.03, 1.45, 0]
        j[I[side + "Arm"]] = [sg * 0.18, 1.45, 0]
        j[I[side + "ForeArm"]] = [sg * 0.46, 1.45, 0]
        j[I[side + "Hand"]] = [sg * 0.72, 1.45, 0]
    return j


def _ends(joints):
    """Far end of each segment's box: the child joint, or a made-up tip."""
    ends = np.zeros_like(joints)
    chain = {0: I["Spine"], I["Spine3"]: I["Neck"]}
    extra_tip = {"Head": [0, 0.22, 0], "LeftHand": [0.18, 0, 0], "RightHand": [-0.18, 0, 0],
                 "LeftFoot": [0, -0.06, 0.16], "RightFoot": [0, -0.06, 0.16]}
    for s in range(N_SEGMENTS):
        kids = np.flatnonzero(PARENTS == s)
        ends[s] = joints[chain.get(s, kids[0])] if len(kids) else joints[s] + extra_tip[SEGMENTS[s]]
    return ends


def _boxes(joints, ends, r=0.03):
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    tri = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                    [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    lo, hi = np.minimum(joints, ends) - r, np.maximum(joints, ends) + r
    vertices = (lo[:, None] + cube[None] * (hi - lo)[:, None]).reshape(-1, 3)
    faces = (tri[None] + 8 * np.arange(len(joints))[:, None, None]).reshape(-1, 3)
    return vertices, faces


def write_skinned_glb(path, *, turn=None, skin=True, names=MH_NAMES, nan=False, bad_face=False,
                      bind_offset=(0.0, 0.0, 0.0), byte_weights=False, buffers="glb"):
    """A GLB of 21 boxes skinned to a 25-joint hierarchy (MakeHuman names + extra joints).

    Every box vertex is weighted to its segment's joint, except that the
    first two vertices of the LeftArm box are split 0.6/0.4 between
    upperarm01.L and the twist joint upperarm02.L, the LeftHand box's first
    vertex goes wholly to a finger joint, and the Hips box's first vertex
    half to spine05: all of them must fold into their segment. With
    ``bind_offset`` the joints are placed there in the node hierarchy and
    the vertices are stored in bind space, so they only come out right when
    the inverse bind matrices are applied. ``byte_weights`` stores the
    weights as normalised unsigned bytes; ``buffers`` is ``"glb"`` (one
    binary chunk), ``"datauri"`` or ``"binfile"`` (a .gltf with an embedded
    or an external buffer). Returns the expected
    (vertices, joints, weights) in seatkit axes.
    """
    joints = _skeleton()
    vertices, faces = _boxes(joints, _ends(joints))
    n = len(vertices)
    # joint list: the 21 segment joints, then the extras
    joint_names = [names.get(s, s) for s in SEGMENTS] + [e[0] for e in EXTRAS]
    joint_parent = list(PARENTS) + [I[e[1]] for e in EXTRAS]
    joint_pos = np.concatenate([joints, [joints[I[e[1]]] + e[2] for e in EXTRAS]])
    J = len(joint_names)
    jidx = np.zeros((n, 4), dtype=np.uint16)
    wts = np.zeros((n, 4), dtype=np.float32)
    seg_of_vertex = np.repeat(np.arange(N_SEGMENTS), 8)
    jidx[:, 0] = seg_of_vertex
    wts[:, 0] = 1.0
    arm0 = 8 * I["LeftArm"]
    jidx[arm0:arm0 + 2, 1] = joint_names.index("upperarm02.L")
    wts[arm0:arm0 + 2, :2] = [0.6, 0.4]
    jidx[8 * I["LeftHand"], 0] = joint_names.index("finger2-1.L")
    jidx[8 * I["Hips"], 1] = joint_names.index("spine05")
    wts[8 * I["Hips"], :2] = [0.5, 0.5]
    expected_w = np.repeat(np.eye(N_SEGMENTS), 8, axis=0)

    turn = np.eye(3) if turn is None else turn
    shift = np.asarray(bind_offset, dtype=float)
    world_joints = joint_pos @ turn.T + shift
    stored_vertices = (vertices @ turn.T).astype(np.float32)  # bind space: joints without the shift
    if nan:
        stored_vertices[5] = np.nan
    face_arr = faces.astype(np.uint32)
    if bad_face:
        face_arr[3, 1] = n + 7
    ibm = np.tile(np.eye(4, dtype=np.float32), (J, 1, 1))
    ibm[:, :3, 3] = -(joint_pos @ turn.T)  # inverse of the bind (unshifted) joint placement
    ibm_bytes = np.ascontiguousarray(ibm.transpose(0, 2, 1)).tobytes()  # column-major

    weight_bytes = np.round(wts * 255).astype(np.uint8).tobytes() if byte_weights else wts.tobytes()
    chunks = [stored_vertices.tobytes(), face_arr.tobytes(), jidx.tobytes(), weight_bytes, ibm_bytes]
    # keep every view 4-byte aligned
    chunks = [c + b"\0" * (-len(c) % 4) for c in chunks]
    offsets = np.cumsum([0] + [len(c) for c in chunks])
    blob = b"".join(chunks)
    views = [pygltflib.BufferView(buffer=0, byteOffset=int(offsets[k]), byteLength=len(chunks[k])) for k in range(5)]
    F = pygltflib.FLOAT
    accessors = [
        pygltflib.Accessor(bufferView=0, componentType=F, count=n, type="VEC3",
                           min=np.nanmin(stored_vertices, 0).tolist(), max=np.nanmax(stored_vertices, 0).tolist()),
        pygltflib.Accessor(bufferView=1, componentType=pygltflib.UNSIGNED_INT, count=face_arr.size, type="SCALAR"),
        pygltflib.Accessor(bufferView=2, componentType=pygltflib.UNSIGNED_SHORT, count=n, type="VEC4"),
        pygltflib.Accessor(bufferView=3, componentType=pygltflib.UNSIGNED_BYTE if byte_weights else F, count=n,
                           type="VEC4", normalized=byte_weights),
        pygltflib.Accessor(bufferView=4, componentType=F, count=J, type="MAT4"),
    ]
    attrs = pygltflib.Attributes(POSITION=0, JOINTS_0=2, WEIGHTS_0=3) if skin else pygltflib.Attributes(POSITION=0)
    mesh = pygltflib.Mesh(primitives=[pygltflib.Primitive(attributes=attrs, indices=1)])
    # nodes 0..J-1: joints (local translations); node J: the mesh; node J+1: armature
    nodes = []
    for k in range(J):
        p = joint_parent[k]
        local = world_joints[k] - (world_joints[p] if p >= 0 else 0.0)
        if p < 0:
            local = world_joints[k]
        nodes.append(pygltflib.Node(name=joint_names[k], translation=local.tolist(),
                                    children=[c for c in range(J) if joint_parent[c] == k]))
    nodes.append(pygltflib.Node(name="body", mesh=0, skin=0 if skin else None))
    nodes.append(pygltflib.Node(name="Armature", children=[0]))
    gltf = pygltflib.GLTF2(
        scene=0,
        scenes=[pygltflib.Scene(nodes=[J, J + 1])],
        nodes=nodes,
        meshes=[mesh],
        skins=[pygltflib.Skin(joints=list(range(J)), inverseBindMatrices=4)] if skin else [],
        accessors=accessors,
        bufferViews=views,
        buffers=[pygltflib.Buffer(byteLength=len(blob))],
    )
    if buffers == "glb":
        gltf.set_binary_blob(blob)
        gltf.save_binary(str(path))
    elif buffers == "datauri":
        gltf.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode("ascii")
        gltf.save(str(path))
    else:  # an external .bin beside the .gltf
        bin_path = path.with_suffix(".bin")
        bin_path.write_bytes(blob)
        gltf.buffers[0].uri = bin_path.name
        gltf.save(str(path))
    return vertices, joints, expected_w


def test_glb_loads_with_weights_and_joints(tmp_path):
    path = tmp_path / "body.glb"
    vertices, joints, weights = write_skinned_glb(path, bind_offset=(0.5, 0.0, -0.25))
    rig = load_gltf_body(path, mass=80.0)
    shift = np.array([0.5, 0.0, -0.25])
    assert rig.vertices.shape == (168, 3) and rig.faces.shape == (252, 3)
    assert np.allclose(rig.vertices, vertices + shift, atol=1e-6)  # joints moved: vertices follow
    assert np.allclose(rig.joints, joints + shift, atol=1e-6)
    assert np.allclose(rig.weights, weights)  # extra joints folded into their segments
    assert np.allclose(rig.weights.sum(axis=1), 1.0) and (rig.weights >= 0).all()
    assert rig.segment_mass.sum() == pytest.approx(80.0)
    # tips: the child joint along the chain, or the far end of the segment's own box
    assert np.allclose(rig.tips[I["LeftArm"]], rig.joints[I["LeftForeArm"]])
    assert np.allclose(rig.tips[I["Hips"]], rig.joints[I["Spine"]])
    assert rig.tips[I["LeftHand"]][0] == pytest.approx(0.72 + 0.18 + 0.03 + 0.5, abs=1e-6)  # box corner
    assert rig.tips[I["Head"]][1] == pytest.approx(1.58 + 0.22 + 0.03, abs=1e-6)
    assert rig.meta["segment_joints"]["LeftHand"] == "wrist.L"
    assert rig.meta["axis_conversion"] == np.eye(3).tolist()
    # it poses: the left forearm box follows a 90-degree elbow bend rigidly
    rot = np.zeros((N_SEGMENTS, 3))
    rot[I["LeftForeArm"]] = [0, -np.pi / 2, 0]
    body = pose_rig(rig, Pose(rot, np.zeros(3)), ground=False)
    fore = slice(8 * I["LeftForeArm"], 8 * I["LeftForeArm"] + 8)
    d = body.vertices[fore] - body.joints[I["LeftForeArm"]]
    d0 = rig.vertices[fore] - rig.joints[I["LeftForeArm"]]
    assert np.allclose(d, d0 @ Rotation.from_rotvec(rot[I["LeftForeArm"]]).as_matrix().T, atol=1e-9)


def test_glb_facing_minus_z_is_turned(tmp_path):
    turn = Rotation.from_euler("Y", 180, degrees=True).as_matrix()
    path = tmp_path / "turned.glb"
    vertices, joints, _ = write_skinned_glb(path, turn=turn)
    rig = load_gltf_body(path)
    assert np.allclose(rig.vertices, vertices, atol=1e-6)
    assert np.allclose(rig.joints, joints, atol=1e-6)
    assert np.allclose(rig.meta["axis_conversion"], turn)


def test_glb_three_spine_joints_split(tmp_path):
    """A Mixamo-like rig without Spine3: the segment is placed and given vertices."""
    names = {**MH_NAMES, "Spine3": "chest_extra"}
    path = tmp_path / "mixamoish.glb"
    write_skinned_glb(path, names=names)
    rig = load_gltf_body(path)
    assert rig.meta["split_segments"] == ["Spine3"]
    assert (rig.weights[:, I["Spine3"]] > 0).any()
    assert np.allclose(rig.weights.sum(axis=1), 1.0)
    spine2, neck = rig.joints[I["Spine2"]], rig.joints[I["Neck"]]
    assert np.allclose(rig.joints[I["Spine3"]], (spine2 + neck) / 2)


def test_glb_user_name_map(tmp_path):
    names = {**MH_NAMES, "LeftHand": "HandL"}
    path = tmp_path / "custom.glb"
    write_skinned_glb(path, names=names)
    with pytest.raises(InputError, match=r"custom\.glb.*LeftHand"):
        load_gltf_body(path)
    rig = load_gltf_body(path, name_map={"segments": {"LeftHand": ["HandL"]}})
    assert rig.meta["segment_joints"]["LeftHand"] == "HandL"


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"skin": False}, r"no skinned mesh"),
        ({"nan": True}, r"NaN"),
        ({"bad_face": True}, r"faces index vertex 175.*168 vertices"),
    ],
)
def test_bad_glb_rejected(tmp_path, kwargs, pattern):
    path = tmp_path / "bad.glb"
    write_skinned_glb(path, **kwargs)
    with pytest.raises(InputError, match=pattern) as err:
        load_gltf_body(path)
    assert "bad.glb" in str(err.value)


def test_not_a_gltf(tmp_path):
    path = tmp_path / "junk.glb"
    path.write_bytes(b"not a glb at all")
    with pytest.raises(InputError, match="junk.glb"):
        load_gltf_body(path)
    with pytest.raises(InputError, match="no such"):
        load_gltf_body(tmp_path / "missing.glb")


def test_load_rig_dispatches_glb(tmp_path):
    from seatkit.body import load_rig

    path = tmp_path / "body.glb"
    write_skinned_glb(path)
    rig = load_rig(path, mass=60.0)
    assert rig.segment_mass.sum() == pytest.approx(60.0)
    assert rig.weights.shape == (168, N_SEGMENTS)


def test_default_body_glb_round_trip(tmp_path):
    """The embedded body written as a GLB (MakeHuman joint names) reads back the same."""
    import trimesh

    from seatkit.body import load_rig
    from seatkit.body.gltf import save_gltf_body
    from seatkit.body.poses import load_pose

    rig = load_rig("default-female")
    path = save_gltf_body(tmp_path / "female.glb", rig)
    scene = trimesh.load(path)  # an independent reader sees the same mesh
    (mesh,) = scene.geometry.values()
    assert len(mesh.vertices) == len(rig.vertices)
    back = load_gltf_body(path, mass=rig.mass, sex="female")
    assert np.abs(back.vertices - rig.vertices).max() < 1e-6
    assert np.abs(back.joints - rig.joints).max() < 1e-6
    # top-4 weights per vertex, renormalised
    few = (rig.weights > 0).sum(axis=1) <= 4
    assert np.abs(back.weights[few] - rig.weights[few]).max() < 1e-6
    assert np.allclose(back.weights.sum(axis=1), 1.0)
    assert np.abs(back.tips - rig.tips).max() < 5e-3
    assert np.allclose(back.segment_mass, rig.segment_mass)
    pose = load_pose("upright-sitting")
    a, b = pose_rig(rig, pose), pose_rig(back, pose)
    assert np.abs(a.joints - b.joints).max() < 1e-5
    assert np.abs(a.vertices[few] - b.vertices[few]).max() < 1e-3


@pytest.mark.parametrize("buffers", ["datauri", "binfile"])
def test_gltf_with_embedded_or_external_buffer_and_byte_weights(tmp_path, buffers):
    path = tmp_path / "body.gltf"
    vertices, joints, weights = write_skinned_glb(path, buffers=buffers, byte_weights=True)
    if buffers == "binfile":
        assert any(p.suffix == ".bin" for p in tmp_path.iterdir())
    rig = load_gltf_body(path)
    assert np.allclose(rig.vertices, vertices, atol=1e-6)
    assert np.allclose(rig.joints, joints, atol=1e-6)
    # 0.6/0.4 stored as bytes 153/102 of 255: read back normalised, then folded into one segment
    assert np.allclose(rig.weights, weights)


def test_sparse_accessor_overrides_base_values():
    from pathlib import Path

    from seatkit.body.gltf import _read_accessor

    base = np.arange(12, dtype=np.float32).reshape(4, 3)
    idx = np.array([1, 3], dtype=np.uint16)
    vals = np.array([[-1, -2, -3], [-4, -5, -6]], dtype=np.float32)
    blob = base.tobytes() + idx.tobytes() + vals.tobytes()
    views = [pygltflib.BufferView(buffer=0, byteOffset=0, byteLength=48),
             pygltflib.BufferView(buffer=0, byteOffset=48, byteLength=4),
             pygltflib.BufferView(buffer=0, byteOffset=52, byteLength=24)]
    sparse = pygltflib.Sparse(
        count=2,
        indices=pygltflib.AccessorSparseIndices(bufferView=1, componentType=pygltflib.UNSIGNED_SHORT),
        values=pygltflib.AccessorSparseValues(bufferView=2),
    )
    gltf = pygltflib.GLTF2(bufferViews=views, accessors=[
        pygltflib.Accessor(bufferView=0, componentType=pygltflib.FLOAT, count=4, type="VEC3", sparse=sparse)])
    out = _read_accessor(gltf, [blob], 0, Path("x.glb"), "POSITION")
    expected = base.astype(np.float64)
    expected[[1, 3]] = vals
    assert np.array_equal(out, expected)
