"""Skinned glTF 2.0 / GLB bodies (Blender, MPFB, MakeHuman exports) as a RiggedBody.

What is read (with :mod:`pygltflib`):

- The first node that has both a mesh and a skin; all its triangle
  primitives (``POSITION``, ``JOINTS_0``/``WEIGHTS_0`` and, if present,
  ``JOINTS_1``/``WEIGHTS_1``, ``indices``), merged.
- The skin's joints, their node hierarchy and ``inverseBindMatrices``.

The rest pose is the pose the file's nodes are in. Following the glTF
specification, a skinned mesh is placed by its joints, not by its own node:
each vertex goes to ``sum_i w_i * G_{j_i} @ IBM_{j_i} @ v`` (``G`` a joint
node's world matrix). glTF is +Y up, metres, and its assets face +Z, as
seatkit; the up (hips to head) and left (right hip to left hip) directions
of the skeleton are checked anyway and the nearest axis-aligned rotation
applied (see :func:`seatkit.body.retarget.facing_rotation`), and recorded in
``meta["axis_conversion"]``.

Joint names go to the 21 segments through a YAML name map
(``seatkit/data/name_maps/gltf-default.yaml``: MakeHuman/MPFB default rig,
Mixamo and Perception Neuron names). Each segment names the joint at its
proximal end; every other skin joint gives its weights to its nearest mapped
ancestor node (twist bones, fingers, toes, eyes, extra spine and neck
joints), and joints above the Hips give theirs to Hips. Segment joints are
the mapped joints' world positions; tips are the next segment's joint, and
for the head, hands and feet the segment's own vertex (largest weight)
farthest along a direction: up for the head, forearm -> hand for a hand,
ankle -> middle of the foot (horizontally) for a foot, as for the embedded
default bodies. A rig with only three back
joints (Mixamo) or no neck/clavicle joint misses a seatkit segment: its
joint is put midway between its neighbours along the chain and it takes
over, with a linear ramp, the weights of its parent segment's vertices lying
beyond that point (``meta["split_segments"]``). Masses follow Plagenhoef et
al. (1983) through :func:`seatkit.body.rig.make_rig`.
"""

from __future__ import annotations

import base64
import math
from pathlib import Path
from typing import Mapping

import numpy as np

from seatkit.body.name_maps import candidate_maps, choose_map, load_name_map
from seatkit.body.retarget import CHAIN_CHILD, check_axes, facing_rotation
from seatkit.body.rig import make_rig
from seatkit.constants import BODY_SIZE_RANGE, DEFAULT_BODY_MASS
from seatkit.errors import InputError
from seatkit.model import RiggedBody
from seatkit.skeleton import N_SEGMENTS, PARENTS, SEGMENT_INDEX, SEGMENTS
from seatkit.messages import quote

__all__ = ["load_gltf_body", "load_gltf_rig", "save_gltf_body"]

_COMPONENT_DTYPES = {
    5120: np.int8,
    5121: np.uint8,
    5122: np.int16,
    5123: np.uint16,
    5125: np.uint32,
    5126: np.float32,
}
_TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_TRIANGLES = 4
#: A body's largest extent must lie in this range, m: a glTF of a person is in
#: metres, so anything smaller is a toy or the wrong unit and anything larger
#: is a mistake (a building, a scaled node, garbage read through a bad stride).
MIN_BODY_SIZE, MAX_BODY_SIZE = BODY_SIZE_RANGE
#: Most nodes, accessor elements and bytes of a body file seatkit reads.
MAX_NODES = 100_000
MAX_COUNT = 50_000_000
#: Largest node translation or scale, and matrix entry, accepted.
MAX_TRANSFORM = 1e4
#: Where along the chain a missing segment's joint is put (0 parent, 1 child).
_SPLIT_AT = 0.5
#: Half-width of the weight ramp around a split point, as a fraction of the chain.
_SPLIT_RAMP = 0.15


def _load_document(path: Path):
    try:
        import pygltflib
    except ImportError as e:  # pygltflib is a core dependency; be clear if it is absent
        msg = f"{path}: reading glTF needs the package pygltflib ({e})"
        raise InputError(msg) from None
    from seatkit.io import MAX_FILE_BYTES, check_user_file

    check_user_file(path, "glTF/GLB file", max_bytes=MAX_FILE_BYTES["glTF"])
    try:
        gltf = pygltflib.GLTF2().load(str(path))
    except Exception as e:  # pygltflib raises many kinds on a bad file
        msg = f"{path}: not a readable glTF/GLB file ({type(e).__name__}: {e})"
        raise InputError(msg) from None
    if gltf is None:
        msg = f"{path}: not a readable glTF/GLB file"
        raise InputError(msg)
    # the top-level arrays seatkit reads: lists of objects of the right kind
    kinds = {
        "nodes": pygltflib.Node,
        "meshes": pygltflib.Mesh,
        "skins": pygltflib.Skin,
        "accessors": pygltflib.Accessor,
        "bufferViews": pygltflib.BufferView,
        "buffers": pygltflib.Buffer,
    }
    for key, kind in kinds.items():
        items = getattr(gltf, key)
        if items is None:
            setattr(gltf, key, [])
            continue
        if not isinstance(items, list):
            msg = f"{path}: {key}: expected a list of objects, got {quote(items)}"
            raise InputError(msg)
        for i, item in enumerate(items):
            if not isinstance(item, kind):
                msg = f"{path}: {key}[{i}]: expected an object, got {quote(item)}"
                raise InputError(msg)
    for m, mesh in enumerate(gltf.meshes):
        prims = mesh.primitives
        if not isinstance(prims, list) or not all(isinstance(q, pygltflib.Primitive) for q in prims):
            msg = f"{path}: meshes[{m}].primitives: expected a list of objects"
            raise InputError(msg)
    return gltf


def _buffers(gltf, path: Path) -> list[bytes]:
    """The bytes of every buffer (GLB chunk, data URI or file beside ``path``)."""
    blobs = []
    for k, buf in enumerate(gltf.buffers):
        uri = buf.uri
        if uri is not None and not isinstance(uri, str):
            msg = f"{path}: buffers[{k}].uri: expected text, got {quote(uri)}"
            raise InputError(msg)
        if uri is None:
            data = gltf.binary_blob()
            if data is None:
                msg = f"{path}: buffer {k} has no URI and the file has no binary chunk"
                raise InputError(msg)
        elif uri.startswith("data:"):
            try:
                data = base64.b64decode(uri.split(",", 1)[1])
            except (IndexError, ValueError) as e:
                msg = f"{path}: buffer {k}: bad data URI ({e})"
                raise InputError(msg) from None
        else:
            # a relative file beside the glTF only: an uploaded file must not
            # make seatkit read /etc/passwd or ../../secrets
            from urllib.parse import unquote

            name = unquote(uri)
            if Path(name).is_absolute() or ".." in Path(name).parts or ":" in name or "\0" in name:
                msg = f"{path}: buffers[{k}].uri {quote(uri)}: expected a file name beside the glTF file"
                raise InputError(msg)
            from seatkit.io import MAX_FILE_BYTES, read_user_file

            try:
                data = read_user_file(path.parent / name, "glTF buffer", max_bytes=MAX_FILE_BYTES["glTF"])
            except InputError as e:
                msg = f"{path}: buffer {k}: cannot read {quote(uri)} ({e})"
                raise InputError(msg) from None
        blobs.append(bytes(data))
    return blobs


def _index(value, n: int, what: str, path: Path, *, lo: int = 0) -> int:
    """``value`` as an integer in ``lo .. n - 1``, or an InputError naming ``what``."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value < n:
        msg = f"{what}: expected a whole number from {lo} to {n - 1}, got {quote(value)}"
        raise InputError(msg)
    return value


def _view_array(gltf, blobs, v: int, offset: int, dtype, ncomp: int, count: int, where: str, path: Path, *, packed=False):
    """``count`` elements of ``ncomp`` components read through bufferView ``v``, bounds-checked."""
    view = gltf.bufferViews[v]
    b = _index(view.buffer, len(blobs), f"{path}: bufferViews[{v}].buffer", path)
    blob = blobs[b]
    view_start = _index(view.byteOffset or 0, 2**40, f"{path}: bufferViews[{v}].byteOffset", path)
    view_length = _index(view.byteLength, 2**40, f"{path}: bufferViews[{v}].byteLength", path, lo=1)
    if view_start + view_length > len(blob):
        msg = f"{path}: bufferViews[{v}]: bytes {view_start}..{view_start + view_length} are beyond buffer {b} ({len(blob)} bytes)"
        raise InputError(msg)
    element = dtype.itemsize * ncomp
    stride = element
    if view.byteStride is not None and not packed:
        stride = view.byteStride
        # glTF 2.0: 4..252, a multiple of 4; and no narrower than one element
        # (byteStride 1 reads overlapping garbage)
        if isinstance(stride, bool) or not isinstance(stride, int) or not 4 <= stride <= 252 or stride % 4 or stride < element:
            msg = f"{path}: bufferViews[{v}].byteStride: expected a multiple of 4 from {max(4, element)} to 252 for {where}, got {quote(stride)}"
            raise InputError(msg)
    end = offset + stride * (count - 1) + element if count else offset
    if end > view_length:
        msg = f"{where}: reads {end} bytes of bufferViews[{v}], which has {view_length}"
        raise InputError(msg)
    return np.ndarray((count, ncomp), dtype=dtype, buffer=blob, offset=view_start + offset, strides=(stride, dtype.itemsize)).copy()


def _read_accessor(gltf, blobs: list[bytes], index: int, path: Path, what: str) -> np.ndarray:
    """Accessor ``index`` as a float64 or int64 array of shape (count, components)."""
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(gltf.accessors):
        msg = f"{path}: {what}: accessor {quote(index)} does not exist (the file has {len(gltf.accessors)})"
        raise InputError(msg)
    acc = gltf.accessors[index]
    where = f"{path}: {what}: accessors[{index}]"
    if acc.componentType not in _COMPONENT_DTYPES or acc.type not in _TYPE_SIZES:
        msg = f"{where}: unsupported componentType/type {quote(acc.componentType)}/{quote(acc.type)}"
        raise InputError(msg)
    dtype = np.dtype(_COMPONENT_DTYPES[acc.componentType]).newbyteorder("<")
    ncomp = _TYPE_SIZES[acc.type]
    count = _index(acc.count, MAX_COUNT + 1, f"{where}.count", path, lo=0)
    offset = _index(acc.byteOffset or 0, 2**40, f"{where}.byteOffset", path, lo=0)
    if acc.bufferView is None:
        out = np.zeros((count, ncomp), dtype=dtype)
    else:
        v = _index(acc.bufferView, len(gltf.bufferViews), f"{where}.bufferView", path)
        out = _view_array(gltf, blobs, v, offset, dtype, ncomp, count, where, path)
    if acc.sparse is not None:
        sp = acc.sparse
        n = _index(getattr(sp, "count", None), count + 1, f"{where}.sparse.count", path, lo=1)
        indices, values = getattr(sp, "indices", None), getattr(sp, "values", None)
        if indices is None or values is None or getattr(indices, "componentType", None) not in (5121, 5123, 5125):
            msg = f"{where}.sparse: expected indices (unsigned byte, short or int) and values"
            raise InputError(msg)
        idx_dtype = np.dtype(_COMPONENT_DTYPES[indices.componentType]).newbyteorder("<")
        iv = _index(indices.bufferView, len(gltf.bufferViews), f"{where}.sparse.indices.bufferView", path)
        vv = _index(values.bufferView, len(gltf.bufferViews), f"{where}.sparse.values.bufferView", path)
        io = _index(indices.byteOffset or 0, 2**40, f"{where}.sparse.indices.byteOffset", path, lo=0)
        vo = _index(values.byteOffset or 0, 2**40, f"{where}.sparse.values.byteOffset", path, lo=0)
        idx = _view_array(gltf, blobs, iv, io, idx_dtype, 1, n, f"{where}.sparse.indices", path, packed=True).ravel()
        vals = _view_array(gltf, blobs, vv, vo, dtype, ncomp, n, f"{where}.sparse.values", path, packed=True)
        if idx.size and int(idx.max()) >= count:
            msg = f"{where}.sparse.indices: index {int(idx.max())} beyond the accessor's {count} elements"
            raise InputError(msg)
        out = out.copy()
        out[idx.astype(np.int64)] = vals
    if np.issubdtype(dtype, np.integer):
        if acc.normalized:
            # normalised integers map to [0, 1] (unsigned) or [-1, 1] (signed)
            return np.maximum(out.astype(np.float64) / np.iinfo(dtype).max, -1.0)
        return out.astype(np.int64)
    with np.errstate(invalid="ignore", over="ignore"):  # NaN payloads: refused by the callers
        return out.astype(np.float64)


def _numbers(value, n: int, what: str, limit: float) -> np.ndarray | None:
    """``value`` as ``n`` finite floats of magnitude <= ``limit`` (None if absent)."""
    if value is None:
        return None
    ok = isinstance(value, (list, tuple)) and len(value) == n
    ok = ok and all(isinstance(x, (int, float)) and not isinstance(x, bool) and abs(x) <= limit for x in value)
    if not ok:
        msg = f"{what}: expected {n} numbers of magnitude at most {limit:g}, got {quote(value)}"
        raise InputError(msg)
    return np.asarray(value, dtype=np.float64)


def _local_matrix(node, where: str) -> np.ndarray:
    """A node's local 4x4 matrix (``matrix`` or translation/rotation/scale)."""
    matrix = _numbers(node.matrix, 16, f"{where}.matrix", MAX_TRANSFORM)
    if matrix is not None:
        return matrix.reshape(4, 4).T  # column-major
    from scipy.spatial.transform import Rotation

    m = np.eye(4)
    scale = _numbers(node.scale, 3, f"{where}.scale", MAX_TRANSFORM)
    rot = _numbers(node.rotation, 4, f"{where}.rotation", 1e3)
    if rot is not None and not np.linalg.norm(rot) > 1e-6:
        msg = f"{where}.rotation: a zero quaternion is not a rotation"
        raise InputError(msg)
    m[:3, :3] = (Rotation.from_quat(rot).as_matrix() if rot is not None else np.eye(3)) * (
        scale[None, :] if scale is not None else 1.0
    )  # quaternion x, y, z, w
    translation = _numbers(node.translation, 3, f"{where}.translation", MAX_TRANSFORM)
    if translation is not None:
        m[:3, 3] = translation
    return m


def _world_matrices(gltf, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """World matrix (k, 4, 4) and parent index (k,) of every node.

    The nodes must form trees (glTF 2.0): children in range, no node with
    two parents, no cycle. Parents are resolved before children without
    recursion, so a chain of 100,000 nodes costs linear time.
    """
    k = len(gltf.nodes)
    if k > MAX_NODES:
        msg = f"{path}: {k} nodes; seatkit reads bodies of at most {MAX_NODES}"
        raise InputError(msg)
    parent = np.full(k, -1, dtype=np.int64)
    for i, node in enumerate(gltf.nodes):
        children = node.children or []
        if not isinstance(children, list):
            msg = f"{path}: nodes[{i}].children: expected a list of node indices, got {quote(children)}"
            raise InputError(msg)
        for c in children:
            _index(c, k, f"{path}: nodes[{i}].children", path)
            if c == i:
                msg = f"{path}: nodes[{i}].children: a node cannot be its own child"
                raise InputError(msg)
            if parent[c] >= 0:
                msg = f"{path}: nodes[{c}] is a child of both nodes[{parent[c]}] and nodes[{i}]; glTF nodes form trees"
                raise InputError(msg)
            parent[c] = i
    local = [_local_matrix(n, f"{path}: nodes[{i}]") for i, n in enumerate(gltf.nodes)]
    world = np.empty((k, 4, 4))
    done = np.zeros(k, dtype=bool)
    children: list[list[int]] = [[] for _ in range(k)]
    for c in range(k):
        if parent[c] >= 0:
            children[parent[c]].append(c)
    todo = [i for i in range(k) if parent[i] < 0]
    while todo:
        i = todo.pop()
        world[i] = local[i] if parent[i] < 0 else world[parent[i]] @ local[i]
        done[i] = True
        todo.extend(children[i])
    if not done.all():
        first = int(np.flatnonzero(~done)[0])
        msg = f"{path}: the node hierarchy has a cycle (through nodes[{first}]); glTF nodes form trees"
        raise InputError(msg)
    if not np.isfinite(world).all():
        first = int(np.flatnonzero(~np.isfinite(world).all(axis=(1, 2)))[0])
        msg = f"{path}: nodes[{first}]: its world transform overflows (nested scales too large)"
        raise InputError(msg)
    return world, parent


def load_gltf_body(
    path: str | Path,
    *,
    name_map: str | Path | Mapping | None = None,
    mass: float = DEFAULT_BODY_MASS,
    sex: str = "male",
) -> RiggedBody:
    """Load a skinned glTF/GLB human as a rest-pose RiggedBody (see the module doc).

    Parameters
    ----------
    path : str or Path
        ``.glb`` or ``.gltf`` (external buffers are read from beside it).
    name_map : str, Path or mapping, optional
        Joint names per segment, laid over ``gltf-default`` (a YAML path, a
        dict, or a built-in map name); ``base: none`` in it replaces the default.
    mass : float
        Total body mass, kg.
    sex : {"male", "female"}
        Column of the Plagenhoef table for the segment masses.

    Returns
    -------
    RiggedBody
        In seatkit axes (m, +Y up, facing +Z); ``meta`` records the source,
        the name map, the joints of each segment and the axis conversion.

    Raises
    ------
    InputError
        No skinned mesh, non-triangle primitives, NaN vertices, faces out of
        range, vertices without weights, needed joints missing (named).
    """
    path = Path(path)
    gltf = _load_document(path)
    skinned = [i for i, n in enumerate(gltf.nodes) if n.mesh is not None and n.skin is not None]
    if not skinned:
        meshes = sum(1 for n in gltf.nodes if n.mesh is not None)
        msg = (
            f"{path}: no skinned mesh (a node with both a mesh and a skin); "
            f"the file has {meshes} mesh node(s) and {len(gltf.skins)} skin(s)"
        )
        raise InputError(msg)
    node = gltf.nodes[skinned[0]]
    skin = gltf.skins[_index(node.skin, len(gltf.skins), f"{path}: nodes[{skinned[0]}].skin", path)]
    mesh = gltf.meshes[_index(node.mesh, len(gltf.meshes), f"{path}: nodes[{skinned[0]}].mesh", path)]
    blobs = _buffers(gltf, path)
    joints_raw = skin.joints if isinstance(skin.joints, list) else None
    if not joints_raw:
        msg = f"{path}: skin {node.skin} has no joints"
        raise InputError(msg)
    for j in joints_raw:
        _index(j, len(gltf.nodes), f"{path}: skins[{node.skin}].joints", path)
    joint_nodes = np.asarray(joints_raw, dtype=np.int64)
    if not isinstance(mesh.primitives, list):
        msg = f"{path}: meshes[{node.mesh}].primitives: expected a list"
        raise InputError(msg)

    # merge the mesh's primitives
    positions, faces, influence_j, influence_w = [], [], [], []
    offset = 0
    for p, prim in enumerate(mesh.primitives):
        where = f"mesh {node.mesh} primitive {p}"
        mode = _TRIANGLES if prim.mode is None else prim.mode
        if mode != _TRIANGLES or isinstance(mode, bool):
            msg = f"{path}: {where}: mode {quote(mode)} is not triangles (4)"
            raise InputError(msg)
        attrs = prim.attributes
        if attrs is None or isinstance(attrs, (str, int, float, list, dict)) or attrs.POSITION is None:
            msg = f"{path}: {where}: no POSITION attribute"
            raise InputError(msg)
        pos = _read_accessor(gltf, blobs, attrs.POSITION, path, f"{where} POSITION")
        n = len(pos)
        if not np.isfinite(pos).all():
            bad = np.flatnonzero(~np.isfinite(pos).all(axis=1))
            msg = f"{path}: {where}: {bad.size} vertices are NaN or infinite (first: vertex {bad[0]})"
            raise InputError(msg)
        if prim.indices is not None:
            tri = _read_accessor(gltf, blobs, prim.indices, path, f"{where} indices").ravel()
        else:
            tri = np.arange(n, dtype=np.int64)
        if tri.size % 3:
            msg = f"{path}: {where}: {tri.size} indices is not a multiple of 3"
            raise InputError(msg)
        if tri.size and (tri.min() < 0 or tri.max() >= n):
            msg = (
                f"{path}: {where}: faces index vertex {int(tri.max())}, "
                f"but the primitive has {n} vertices (0..{n - 1})"
            )
            raise InputError(msg)
        js, ws = [], []
        for set_no in range(8):
            jname, wname = f"JOINTS_{set_no}", f"WEIGHTS_{set_no}"
            jacc, wacc = getattr(attrs, jname, None), getattr(attrs, wname, None)
            if jacc is None or wacc is None:
                break
            joints_set = _read_accessor(gltf, blobs, jacc, path, f"{where} {jname}")
            if not np.issubdtype(joints_set.dtype, np.integer):
                msg = f"{path}: {where} {jname}: expected unsigned byte or short joint indices, got floats"
                raise InputError(msg)
            js.append(joints_set)
            ws.append(_read_accessor(gltf, blobs, wacc, path, f"{where} {wname}"))
        if not js:
            msg = f"{path}: {where}: no JOINTS_0/WEIGHTS_0 (the mesh is not skinned)"
            raise InputError(msg)
        for k, (jset, wset) in enumerate(zip(js, ws)):
            if jset.shape != wset.shape:
                msg = f"{path}: {where}: JOINTS_{k} has {jset.shape[1]} components per vertex but WEIGHTS_{k} {wset.shape[1]}"
                raise InputError(msg)
        j_arr, w_arr = np.concatenate(js, axis=1), np.concatenate(ws, axis=1)
        if j_arr.shape[0] != n or w_arr.shape[0] != n:
            msg = f"{path}: {where}: JOINTS/WEIGHTS count differs from POSITION ({n})"
            raise InputError(msg)
        used = w_arr > 0
        if (j_arr[used] >= len(joint_nodes)).any() or (j_arr[used] < 0).any():
            msg = f"{path}: {where}: JOINTS index beyond the skin's {len(joint_nodes)} joints"
            raise InputError(msg)
        if not np.isfinite(w_arr).all() or (w_arr < 0).any():
            msg = f"{path}: {where}: WEIGHTS must be finite and non-negative"
            raise InputError(msg)
        positions.append(pos)
        faces.append(tri.reshape(-1, 3) + offset)
        influence_j.append(np.where(used, j_arr, 0))
        influence_w.append(w_arr)
        offset += n
    if not positions:
        msg = f"{path}: mesh {node.mesh} has no primitives"
        raise InputError(msg)
    vertices_local = np.concatenate(positions)
    faces_all = np.concatenate(faces).astype(np.int64)
    inf_j, inf_w = np.concatenate(influence_j), np.concatenate(influence_w)
    total = inf_w.sum(axis=1)
    if (total <= 0).any():
        bad = np.flatnonzero(total <= 0)
        msg = f"{path}: {bad.size} vertices have no skin weight (first: vertex {bad[0]})"
        raise InputError(msg)
    inf_w = inf_w / total[:, None]

    # rest pose = the file's node pose: v -> sum_i w_i G_j IBM_j v
    world, node_parent = _world_matrices(gltf, path)
    if skin.inverseBindMatrices is not None:
        ibm = _read_accessor(gltf, blobs, skin.inverseBindMatrices, path, "inverseBindMatrices")
        if ibm.shape != (len(joint_nodes), 16):
            msg = f"{path}: inverseBindMatrices has {ibm.shape[0]} matrices for {len(joint_nodes)} joints"
            raise InputError(msg)
        if not (np.isfinite(ibm).all() and np.abs(ibm).max() <= MAX_TRANSFORM):
            msg = f"{path}: inverseBindMatrices: entries must be finite and at most {MAX_TRANSFORM:g} in magnitude"
            raise InputError(msg)
        ibm = ibm.reshape(-1, 4, 4).transpose(0, 2, 1)  # column-major
    else:
        ibm = np.tile(np.eye(4), (len(joint_nodes), 1, 1))
    skin_mats = world[joint_nodes] @ ibm  # (J, 4, 4)
    blended = np.einsum("ni,nijk->njk", inf_w, skin_mats[inf_j])  # (n, 4, 4)
    homog = np.concatenate([vertices_local, np.ones((len(vertices_local), 1))], axis=1)
    vertices = np.einsum("nij,nj->ni", blended, homog)[:, :3]
    joint_pos = world[joint_nodes, :3, 3]
    size = float(np.ptp(vertices, axis=0).max()) if np.isfinite(vertices).all() else math.inf
    if not MIN_BODY_SIZE <= size <= MAX_BODY_SIZE:
        shown = "not finite" if not math.isfinite(size) else f"{size:.3g} m across"
        msg = (
            f"{path}: the skinned body is {shown}; expected a person from {MIN_BODY_SIZE:g} to "
            f"{MAX_BODY_SIZE:g} m (glTF is in metres: check the export's unit scale)"
        )
        raise InputError(msg)

    # names -> segments
    names = [n if isinstance(n := gltf.nodes[int(j)].name, str) and n else f"node{int(j)}" for j in joint_nodes]
    maps = candidate_maps(name_map, ("gltf-default",))
    nm, seg_joint = choose_map(names, maps)
    missing = nm.missing(seg_joint)
    if missing:
        wanted = "; ".join(f"{s} ({' or '.join(nm.segments.get(s, ())) or 'no name in the map'})" for s in missing)
        msg = f"{path}: skin lacks joints needed for segment(s) {wanted} (name map {nm.name})"
        raise InputError(msg)
    # each skin joint -> segment of its nearest mapped ancestor (itself included), default Hips
    node_segment = {int(joint_nodes[seg_joint[s]]): s for s in range(N_SEGMENTS) if seg_joint[s] >= 0}
    joint_segment = np.zeros(len(joint_nodes), dtype=np.int64)
    for k, nd in enumerate(joint_nodes):
        cur = int(nd)
        while cur >= 0 and cur not in node_segment:
            cur = int(node_parent[cur])
        joint_segment[k] = node_segment.get(cur, 0)
    weights = np.zeros((len(vertices), N_SEGMENTS))
    rows = np.repeat(np.arange(len(vertices)), inf_j.shape[1])
    np.add.at(weights, (rows, joint_segment[inf_j].ravel()), inf_w.ravel())

    # axes: check the skeleton is +Y up and faces +Z
    seg_pos = np.full((N_SEGMENTS, 3), np.nan)
    have = seg_joint >= 0
    seg_pos[have] = joint_pos[seg_joint[have]]
    left = seg_pos[SEGMENT_INDEX["LeftUpLeg"]] - seg_pos[SEGMENT_INDEX["RightUpLeg"]]
    up = seg_pos[SEGMENT_INDEX["Head"]] - seg_pos[0]
    check_axes(left, up, size, str(path))
    A = facing_rotation(left, up)
    vertices = vertices @ A.T
    seg_pos = seg_pos @ A.T

    joints, weights, split = _fill_missing_segments(seg_pos, weights, vertices, path)
    tips = _segment_tips(joints, weights, vertices, path)
    meta = {
        "source": str(path),
        "format": "glTF",
        "name_map": nm.name,
        "segment_joints": {SEGMENTS[s]: names[seg_joint[s]] for s in range(N_SEGMENTS) if seg_joint[s] >= 0},
        "split_segments": split,
        "axis_conversion": A.round(12).tolist(),
        "sex": sex,
    }
    return make_rig(
        vertices,
        faces_all,
        weights,
        joints,
        tips,
        mass=mass,
        sex=sex,
        name=str(path),
        meta=meta,
        source=str(path),
    )


def _fill_missing_segments(joints: np.ndarray, weights: np.ndarray, vertices: np.ndarray, path: Path):
    """Place the joints of segments the skin lacks and give them vertices (module doc).

    Returns
    -------
    joints : (21, 3) float64
    weights : (n, 21) float64
    split : list of str
        The segments that were made up.
    """
    joints = joints.copy()
    weights = weights.copy()
    split = []
    for s in range(N_SEGMENTS):
        if not np.isnan(joints[s]).any():
            continue
        # run of missing segments from s down the chain, between mapped a and d
        run = [s]
        d = int(CHAIN_CHILD[s])
        while d >= 0 and np.isnan(joints[d]).any():
            run.append(d)
            d = int(CHAIN_CHILD[d])
        a = int(PARENTS[s])
        if d < 0 or a < 0:
            msg = f"{path}: segment {SEGMENTS[s]} has no joint, and no joints around it to place it by"
            raise InputError(msg)
        chain = joints[d] - joints[a]
        length2 = float(chain @ chain)
        # position of every vertex along a -> d, 0..1
        t = (vertices - joints[a]) @ chain / max(length2, 1e-12)
        for k, seg in enumerate(run, start=1):
            at = k / (len(run) + 1) if len(run) > 1 else _SPLIT_AT
            joints[seg] = joints[a] + at * chain
        # hand the parent's weight beyond each split point over, with a ramp
        owner = a
        for k, seg in enumerate(run, start=1):
            at = k / (len(run) + 1) if len(run) > 1 else _SPLIT_AT
            share = np.clip((t - (at - _SPLIT_RAMP)) / (2 * _SPLIT_RAMP), 0.0, 1.0)
            moved = weights[:, owner] * share
            weights[:, owner] -= moved
            weights[:, seg] += moved
            owner = seg
            split.append(SEGMENTS[seg])
    return joints, weights, split


def _segment_tips(joints: np.ndarray, weights: np.ndarray, vertices: np.ndarray, path: Path | str = "<glTF>") -> np.ndarray:
    """Distal end of each segment (module doc)."""
    tips = np.empty_like(joints)
    dominant = np.argmax(weights, axis=1)
    for s in range(N_SEGMENTS):
        c = CHAIN_CHILD[s]
        if c >= 0:
            tips[s] = joints[c]
            continue
        own = vertices[dominant == s]
        if len(own) == 0:
            own = vertices[weights[:, s] > 0]
        name = SEGMENTS[s]
        if len(own) == 0:
            msg = f"{path}: segment {name} has no skinned vertices (no vertex weighted to its joints)"
            raise InputError(msg)
        if name == "Head":
            direction = np.array([0.0, 1.0, 0.0])
        elif name.endswith("Foot"):
            # along the foot: ankle to the middle of the foot, horizontally
            direction = own.mean(axis=0) - joints[s]
            direction[1] = 0.0
        else:  # hands: along the forearm
            direction = joints[s] - joints[PARENTS[s]]
        tips[s] = own[np.argmax((own - joints[s]) @ direction)]
    return tips


#: The name :func:`seatkit.body.loading.load_rig` imports.
load_gltf_rig = load_gltf_body


def save_gltf_body(
    path: str | Path,
    rig: RiggedBody,
    *,
    naming: str | Path | Mapping = "gltf-default",
    influences: int = 4,
) -> Path:
    """Write a rig as a skinned GLB (21 joints, for Blender and other tools).

    Each segment becomes a joint node named by the first name the map gives
    it, placed at the segment's rest joint (no rotation), with the inverse
    bind matrix of that placement. Each vertex keeps its ``influences``
    largest segment weights, renormalised to sum to 1.

    Parameters
    ----------
    path : str or Path
        ``.glb`` file, written atomically.
    rig : RiggedBody
    naming : str, Path or mapping
        Name map for the joint names (default MakeHuman names).
    influences : int
        Weights kept per vertex (4 fills one JOINTS_0/WEIGHTS_0 pair).

    Returns
    -------
    Path
    """
    import pygltflib

    from seatkit.io import write_bytes_atomic

    nm = load_name_map(naming)
    names = [(nm.segments.get(seg) or (seg,))[0] for seg in SEGMENTS]
    vertices = np.asarray(rig.vertices, dtype=np.float32)
    faces = np.asarray(rig.faces, dtype=np.uint32)
    joints = np.asarray(rig.joints, dtype=np.float64)
    n = len(vertices)
    k = int(np.clip(influences, 1, N_SEGMENTS))
    sets = -(-k // 4)  # JOINTS_i/WEIGHTS_i pairs of 4
    # the k largest weights per vertex, renormalised
    top = np.argsort(-rig.weights, axis=1)[:, :k]
    top_w = np.take_along_axis(rig.weights, top, axis=1)
    top_w = top_w / top_w.sum(axis=1, keepdims=True)
    jidx = np.zeros((n, 4 * sets), dtype=np.uint16)
    wts = np.zeros((n, 4 * sets), dtype=np.float32)
    jidx[:, :k], wts[:, :k] = top, top_w
    ibm = np.tile(np.eye(4, dtype=np.float32), (N_SEGMENTS, 1, 1))
    ibm[:, :3, 3] = -joints
    chunks = [vertices.tobytes(), faces.tobytes()]
    for i in range(sets):
        block = slice(4 * i, 4 * i + 4)
        chunks += [np.ascontiguousarray(jidx[:, block]).tobytes(), np.ascontiguousarray(wts[:, block]).tobytes()]
    chunks.append(np.ascontiguousarray(ibm.transpose(0, 2, 1)).tobytes())  # column-major
    offsets = np.cumsum([0] + [len(c) for c in chunks])
    views = [
        pygltflib.BufferView(buffer=0, byteOffset=int(offsets[i]), byteLength=len(c)) for i, c in enumerate(chunks)
    ]
    accessors = [
        pygltflib.Accessor(bufferView=0, componentType=pygltflib.FLOAT, count=n, type="VEC3",
                           min=vertices.min(axis=0).tolist(), max=vertices.max(axis=0).tolist()),
        pygltflib.Accessor(bufferView=1, componentType=pygltflib.UNSIGNED_INT, count=faces.size, type="SCALAR"),
    ]
    skin_attrs = {}
    for i in range(sets):
        skin_attrs[f"JOINTS_{i}"] = len(accessors)
        accessors.append(
            pygltflib.Accessor(bufferView=2 + 2 * i, componentType=pygltflib.UNSIGNED_SHORT, count=n, type="VEC4")
        )
        skin_attrs[f"WEIGHTS_{i}"] = len(accessors)
        accessors.append(pygltflib.Accessor(bufferView=3 + 2 * i, componentType=pygltflib.FLOAT, count=n, type="VEC4"))
    accessors.append(
        pygltflib.Accessor(bufferView=len(chunks) - 1, componentType=pygltflib.FLOAT, count=N_SEGMENTS, type="MAT4")
    )
    nodes = []
    for s in range(N_SEGMENTS):
        parent = PARENTS[s]
        local = joints[s] - (joints[parent] if parent >= 0 else 0.0)
        nodes.append(pygltflib.Node(name=names[s], translation=local.tolist(),
                                    children=[int(c) for c in np.flatnonzero(PARENTS == s)]))
    nodes.append(pygltflib.Node(name=rig.name or "body", mesh=0, skin=0))
    attributes = pygltflib.Attributes(POSITION=0, **skin_attrs)
    gltf = pygltflib.GLTF2(
        scene=0,
        scenes=[pygltflib.Scene(nodes=[0, N_SEGMENTS])],
        nodes=nodes,
        meshes=[pygltflib.Mesh(primitives=[pygltflib.Primitive(attributes=attributes, indices=1)])],
        skins=[pygltflib.Skin(joints=list(range(N_SEGMENTS)), inverseBindMatrices=len(accessors) - 1)],
        accessors=accessors,
        bufferViews=views,
        buffers=[pygltflib.Buffer(byteLength=int(offsets[-1]))],
    )
    gltf.set_binary_blob(b"".join(chunks))
    path = Path(path)
    write_bytes_atomic(path, b"".join(gltf.save_to_bytes()))
    return path
