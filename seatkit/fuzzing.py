"""Fuzzing seatkit's file loaders: mutated inputs, what must happen, a tally.

Every loader of a file a user gives (recipe, template and pose YAML, BVH,
glTF/GLB, OBJ and USD cages, ``.npz`` rigs, ``design.npz``, CSV and YAML
batch tables, name maps) is a :class:`Target`: a few valid seed files, a function
that loads one file the way the CLI does (and the first stage after it), and
an oracle for what an *accepted* file must satisfy. :func:`mutate` turns a
seed into a malformed variant (byte flips, truncation, spliced-in tokens:
NaN, infinities, huge and fractional numbers, quoted booleans, deep nesting,
YAML alias bombs, non-UTF-8 bytes; glTF also gets JSON-level edits of its
indices, counts and strides; USD numbers, tokens and arrays spliced into its
text; ``.npz`` files edits of their arrays and of design.npz's JSON header). :func:`run_case` classifies the outcome:

``ok``
    The loader refused the file with seatkit's own error, on one line of at
    most :data:`MAX_MESSAGE` characters that names the file.
``accepted``
    The file loaded and the oracle holds (finite values in a physical range).
``crash``
    Any other exception (signature: type and innermost seatkit frame), a
    message that is not one bounded line naming the file, or an accepted file
    the oracle rejects (a silently wrong answer).
``hang``
    The case ran longer than the time limit.

The test suite drives :func:`mutate` with hypothesis
(``tests/test_fuzz_loaders.py``); ``tools/fuzz_loaders.py`` runs 10,000
cases per loader and prints the tally (docs/robustness.md).
"""

from __future__ import annotations

import json
import math
import random
import signal
import struct
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol

import numpy as np

from seatkit.errors import RecipeError, SeatkitError

#: Longest error message a loader may print, characters.
MAX_MESSAGE = 500

#: Values spliced into inputs: the ones that crashed or fooled the loaders.
INTERESTING_NUMBERS = (
    "nan", ".nan", "NaN", "inf", ".inf", "-.inf", "-inf", "1e308", "-1e308", "1e400", "1e17", "1e30",
    "-1", "0", "1.0", "2.5", "1.0e+12", "99999999999999999999999", "4294967296", "-0", "1e-320",
)
INTERESTING_YAML = (
    "'false'", "'no'", "'true'", "yes", "~", "[]", "{}", "[1, 2]", "{x: 1}", "!!binary ????", "2001-02-30",
    "&r [*r]", "&a {x: *a}", "*undefined", "!!python/object:os.system x", "'" + "x" * 5000 + "'",
    "1" * 5000, "\"\\uD800\"", "? [a]\n", "- - - - -", "\"a\\0.yaml\"", "'" + "a" * 5000 + ".yaml'", "'../x.glb'",
    "{path: 3}", "{mass: " + "9" * 400 + "}",
)


class Chooser(Protocol):
    """What :func:`mutate` draws its choices from (``random.Random`` or hypothesis)."""

    def randrange(self, n: int) -> int: ...


def _pick(r: Chooser, seq):
    return seq[r.randrange(len(seq))]


def alias_bomb(levels: int = 9, width: int = 9) -> str:
    """A YAML "billion laughs": ``levels`` anchors, each ``width`` aliases of the one before
    (a few hundred bytes that expand to ``9 * width ** (levels - 1)`` values)."""
    out = ["x0: &a0 [1, 2, 3, 4, 5, 6, 7, 8, 9]"]
    for k in range(1, levels):
        out.append(f"x{k}: &a{k} [{', '.join([f'*a{k - 1}'] * width)}]")
    return "\n".join(out) + "\n"


def chain_bvh(n: int) -> str:
    """A BVH whose hierarchy is one chain of ``n`` joints (the issue's 3 MB file had 100,000)."""
    out = ["HIERARCHY", "ROOT j0", "{", "  OFFSET 0 0 0", "  CHANNELS 3 Zrotation Xrotation Yrotation"]
    for k in range(1, n):
        out += [f"JOINT j{k}", "{", "  OFFSET 0 1 0", "  CHANNELS 3 Zrotation Xrotation Yrotation"]
    out += ["}"] * n
    out += ["MOTION", "Frames: 1", "Frame Time: 0.04", " ".join(["0"] * (3 * n))]
    return "\n".join(out) + "\n"


def _deep(n: int) -> str:
    return "[" * n + "1" + "]" * n


# --------------------------------------------------------------------------- mutations


def _splice(data: bytes, r: Chooser, token: bytes) -> bytes:
    at = r.randrange(len(data) + 1)
    return data[:at] + token + data[at:]


def _replace_token(data: bytes, r: Chooser, token: bytes) -> bytes:
    """Replace one number-like or word token with ``token``."""
    import re

    spans = [m.span() for m in re.finditer(rb"-?[0-9][0-9.eE+-]*|\b(?:true|false|[A-Za-z_]+)\b", data[:200_000])]
    if not spans:
        return _splice(data, r, token)
    a, b = _pick(r, spans)
    return data[:a] + token + data[b:]


def _text_mutation(data: bytes, r: Chooser, *, yaml: bool) -> bytes:
    kind = r.randrange(11 if yaml else 9)
    n = len(data)
    if kind == 0 and n:  # bit flip
        at = r.randrange(n)
        return data[:at] + bytes([data[at] ^ (1 << r.randrange(8))]) + data[at + 1 :]
    if kind == 1 and n:  # delete a span
        a = r.randrange(n)
        return data[:a] + data[a + 1 + r.randrange(min(64, n - a)) :]
    if kind == 2:  # truncate
        return data[: r.randrange(n + 1)]
    if kind == 3 and n:  # duplicate a span
        a = r.randrange(n)
        b = min(n, a + 1 + r.randrange(200))
        return data[:b] + data[a:b] + data[b:]
    if kind == 4:  # non-UTF-8 or control bytes
        return _splice(data, r, _pick(r, (b"\xff", b"\xc3", b"\x80\x80", b"\x00", b"\x1b", b"\xef\xbf\xbe", b"\r")))
    if kind == 5:  # swap two lines
        lines = data.split(b"\n")
        if len(lines) > 2:
            i, j = r.randrange(len(lines)), r.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
        return b"\n".join(lines)
    if kind in (6, 7):  # a number or word becomes an interesting number
        return _replace_token(data, r, _pick(r, INTERESTING_NUMBERS).encode())
    if kind == 8:  # a random byte inserted
        return _splice(data, r, bytes([r.randrange(256)]))
    if kind == 9:  # a YAML value becomes an interesting one
        return _replace_token(data, r, _pick(r, INTERESTING_YAML).encode())
    # kind 10: a whole hostile document appended or put in place of one value
    bomb = _pick(r, (alias_bomb(), alias_bomb(12, 12), "a: " + _deep(200), "a: " + _deep(5000), "a: &r {x: *r}"))
    if r.randrange(2):
        return bomb.encode()
    return _replace_token(data, r, bomb.split(": ", 1)[1].strip().encode())


def mutate(data: bytes, r: Chooser, *, yaml: bool = False, n: int | None = None) -> bytes:
    """Apply 1 to 3 random mutations to ``data``."""
    for _ in range(1 + r.randrange(3) if n is None else n):
        data = _text_mutation(data, r, yaml=yaml)
    return data


# glTF: edit the JSON of a GLB (indices, counts, strides, matrices, types)

_GLTF_VALUES = (
    -1, 0, 1, 2, 3, 7, 255, 2**31, 2**53, 1.5, 1e308, -1e308, "x", None, [], {}, [-1], [0, 0], True,
    [1e308] * 16, [0.0] * 16, [float("nan")] * 3, [1e30, 0, 0], [0, 0, 0, 0], [0, 0, 0], 5126, 5123, "VEC3", "MAT4",
)


def _json_paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _json_paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj[:64]):
            yield from _json_paths(v, prefix + (i,))


def split_glb(data: bytes) -> tuple[dict, bytes]:
    """(JSON, BIN chunk) of a GLB."""
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + length])
    rest = data[20 + length :]
    blob = rest[8:] if len(rest) >= 8 else b""
    return doc, blob


def join_glb(doc, blob: bytes) -> bytes:
    """A GLB of a JSON document and a BIN chunk (both padded to 4 bytes)."""
    js = json.dumps(doc, allow_nan=True).encode()
    js += b" " * (-len(js) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def mutate_gltf(data: bytes, r: Chooser) -> bytes:
    """A GLB with 1 to 3 JSON edits, or (one time in four) byte-level mutations."""
    if r.randrange(4) == 0:
        return mutate(data, r)
    doc, blob = split_glb(data)
    for _ in range(1 + r.randrange(3)):
        try:
            _edit_json(doc, r)
        except (TypeError, KeyError, IndexError, AttributeError, ValueError):
            pass  # an earlier edit changed the shape this one expected
    if r.randrange(4) == 0 and blob:
        blob = mutate(blob, r, n=1)
    return join_glb(doc, blob)


def _edit_json(doc, r: Chooser) -> None:
    """One edit of the glTF JSON: a deleted key, a scaled number, a stride, children, a transform, a value."""
    paths = [p for p in _json_paths(doc) if p]
    path = _pick(r, paths)
    parent = doc
    for part in path[:-1]:
        parent = parent[part]
    kind = r.randrange(6)
    if kind == 0 and isinstance(parent, dict):
        del parent[path[-1]]
    elif kind == 1 and isinstance(parent[path[-1]], (int, float)) and not isinstance(parent[path[-1]], bool):
        parent[path[-1]] = parent[path[-1]] * _pick(r, (-1, 2, 1000, 1e6, 1e30, 0.5)) + _pick(r, (0, 1, -1))
    elif kind == 2:  # byteStride, the garbage reader
        views = doc.get("bufferViews") or []
        if views:
            _pick(r, views)["byteStride"] = _pick(r, (1, 2, 3, 4, 5, 8, 12, 13, 256, 0, -4))
    elif kind == 3:  # a node hierarchy edit: cycles, self-children, out-of-range children
        nodes = doc.get("nodes") or []
        if nodes:
            _pick(r, nodes)["children"] = [_pick(r, (-1, 0, len(nodes) - 1, len(nodes), r.randrange(max(len(nodes), 1))))]
    elif kind == 4:  # scale or translate the scene: kilometre bodies
        nodes = doc.get("nodes") or []
        if nodes:
            node = _pick(r, nodes)
            node.pop("matrix", None)
            node[_pick(r, ("scale", "translation"))] = [_pick(r, (1e3, 1e6, 1e308, 0.0, -1.0, 1e-9))] * 3
    else:
        parent[path[-1]] = _pick(r, _GLTF_VALUES)


# --------------------------------------------------------------------------- targets


@dataclass
class Target:
    """One loader under fuzzing.

    Attributes
    ----------
    name : str
    suffix : str
        File suffix the mutated input is written with.
    seeds : list of bytes
        Valid inputs to mutate.
    load : callable
        ``load(path) -> result``: what the CLI does with such a file (and the
        first stage after loading, when that is cheap).
    check : callable
        ``check(result) -> str | None``: why an accepted result is wrong.
    mutate : callable
        ``mutate(data, chooser) -> bytes``.
    """

    name: str
    suffix: str
    seeds: list
    load: Callable
    check: Callable
    mutate: Callable = field(default=None)

    def __repr__(self) -> str:  # not the seeds' bytes (a glTF seed is 800 kB)
        return f"Target({self.name!r}, {len(self.seeds)} seeds)"


def _finite_in(values, lo: float, hi: float) -> bool:
    a = np.asarray(values, dtype=np.float64)
    return bool(np.isfinite(a).all() and (a >= lo).all() and (a <= hi).all())


def _check_recipe_result(recipe) -> str | None:
    from seatkit.recipe import LIMITS
    from seatkit.template.schema import PARAMETERS, parameter_problem

    p = recipe["pressure"]
    if p["lambda"] != math.inf and not _finite_in([p["lambda"]], *LIMITS["lambda"][:2]):
        return f"lambda {p['lambda']!r} accepted"
    if not _finite_in([p["mu"]], *LIMITS["mu"][:2]):
        return f"mu {p['mu']!r} accepted"
    if not _finite_in([recipe["evaluate"]["support_distance"]], *LIMITS["support_distance"][:2]):
        return "support_distance accepted out of range"
    for key in ("seed", "surface_level"):
        if not isinstance(recipe[key], int) or isinstance(recipe[key], bool):
            return f"{key} {recipe[key]!r} is not an integer"
    for body in recipe["bodies"]:
        if not isinstance(body.get("frame", 0), int) or isinstance(body.get("frame", 0), bool):
            return f"frame {body['frame']!r} is not an integer"
        if "offset" in body and not _finite_in(body["offset"], *LIMITS["offset"][:2]):
            return "offset accepted out of range"
    if not isinstance(recipe["evaluate"]["enabled"], bool):
        return "evaluate.enabled is not a boolean"
    for key, value in recipe["template_params"].items():
        if key in PARAMETERS and parameter_problem(key, value):
            return f"template_params.{key} {value!r} accepted"
    return None


def _recipe_target(tmp: Path) -> Target:
    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import check_recipe, load_recipe
    from seatkit.template.schema import resolve_parameters

    registry = get_plugin_manager().registry
    seeds = [
        b"""name: fuzz
template: chair
template_params: {ransac_iterations: 300, support_distance: 0.02, m_alpha_deg: 30}
bodies:
  - model: default-male
    params: {mass: 75}
    pose: upright-sitting
    frame: 0
    offset: [0, 0, 0]
placement: {gap: 0.1}
pressure: {solver: qp, lambda: 0.013, mu: 0.5, exclude: [Head]}
refiners: [optimize, {name: catmull-clark-fit, params: {}}]
exporters: [usd, obj]
surface_level: 3
evaluate: {enabled: true, baseline: flat-patch, support_distance: 0.02}
output: out/fuzz
seed: 7
""",
        b"template: bench\nbodies:\n  - {pose: reclined-sitting, model: default-female}\n  - {pose: lounger}\npressure: {lambda: inf}\n",
    ]
    examples = Path(__file__).resolve().parent.parent / "examples" / "recipes"  # in a source checkout
    seeds += [p.read_bytes() for p in sorted(examples.glob("*.yaml"))]

    def load(path):
        recipe, doc = load_recipe(path)
        check_recipe(recipe, registry, document=doc)
        template = registry.get("template", recipe["template"])
        spec = getattr(template, "spec", None)
        if spec is not None:
            try:
                resolve_parameters(spec, recipe["template_params"])
            except RecipeError as e:
                # the template engine reports these as "template_params.key: ..."
                # without the recipe's file:line; the file is added here to keep
                # fuzzing the values
                raise RecipeError(f"{path}: {e}") from None
        return recipe

    return Target("recipe YAML", ".yaml", seeds, load, _check_recipe_result, lambda d, r: mutate(d, r, yaml=True))


def _check_template_result(template) -> str | None:
    from seatkit.template.schema import parameter_problem

    spec = template.spec
    for key, value in spec.parameters.items():
        if parameter_problem(key, value):
            return f"parameter {key} {value!r} accepted"
    lo, hi = spec.people
    if not (isinstance(lo, int) and isinstance(hi, int) and 1 <= lo <= hi):
        return f"people {spec.people!r} accepted"
    for f in spec.faces.values():
        if not (0 < f.width_fraction <= 1):
            return "width_fraction accepted out of range"
    return None


def _template_target(tmp: Path) -> Target:
    from seatkit.resources import templates_dir
    from seatkit.template.engine import load_template
    from seatkit.template.schema import resolve_parameters

    seeds = [p.read_bytes() for p in sorted(templates_dir().glob("*.yaml"))]

    def load(path):
        template = load_template(path)
        resolve_parameters(template.spec, {})
        return template

    return Target("template YAML", ".yaml", seeds, load, _check_template_result, lambda d, r: mutate(d, r, yaml=True))


def _check_pose_result(pose) -> str | None:
    from seatkit.body.poses import MAX_TRANSLATION

    if not np.isfinite(pose.rotations).all():
        return "pose rotations not finite"
    if not _finite_in(pose.translation, -MAX_TRANSLATION, MAX_TRANSLATION):
        return f"pose translation {np.asarray(pose.translation).tolist()} accepted"
    return None


def _pose_target(tmp: Path) -> Target:
    from seatkit.body.poses import load_pose_file
    from seatkit.resources import data_path

    seeds = [p.read_bytes() for p in sorted(data_path("poses").glob("*.yaml"))]
    seeds.append(b"base: upright-sitting\nsupported: true\nroot:\n  rotation: {x: -10}\n  translation: [0.1, 0.2, -0.3]\njoints:\n  RightLeg: {x: 20, y: 0, z: 5}\n")

    def load(path):
        return load_pose_file(path).to_pose(name="fuzz")

    return Target("pose YAML", ".yaml", seeds, load, _check_pose_result, lambda d, r: mutate(d, r, yaml=True))


def _default_rig():
    from seatkit.body import load_rig

    return load_rig("default-male")


def _coarse_rig(rig, keep: int = 30):
    """The rig with every ``keep``-th triangle (and only the vertices they use):
    the same skeleton, weights and size (2,535 vertices), loaded 2x faster, so that 10,000 glTF
    cases take minutes."""
    from seatkit.body.rig import make_rig

    faces = np.asarray(rig.faces)[::keep]
    used, inverse = np.unique(faces, return_inverse=True)
    return make_rig(
        np.asarray(rig.vertices)[used], inverse.reshape(-1, 3), np.asarray(rig.weights)[used], rig.joints, rig.tips,
        mass=rig.mass, name="coarse",
    )


def _bvh_target(tmp: Path) -> Target:
    from seatkit.body import load_pose
    from seatkit.body.bvh import load_bvh, write_bvh

    rig = _default_rig()
    seeds = []
    for k, (poses, naming) in enumerate(
        [
            (["upright-sitting"], "perception-neuron"),
            (["reclined-sitting", "lounger"], "cmu"),
            (["crossed-legs-knees"], "mixamo"),
        ]
    ):
        path = write_bvh(tmp / f"seed{k}.bvh", [load_pose(p) for p in poses], rig, naming)
        seeds.append(path.read_bytes())

    def load(path):
        return load_bvh(path, rig=rig, root_motion=True)

    def check(pose):
        if not np.isfinite(pose.rotations).all():
            return "BVH pose rotations not finite"
        if not _finite_in(pose.translation, -1e3, 1e3):
            return f"BVH root motion {np.asarray(pose.translation).tolist()} m accepted"
        return None

    return Target("BVH", ".bvh", seeds, load, check, mutate)


def _gltf_target(tmp: Path) -> Target:
    from seatkit.body.gltf import MAX_BODY_SIZE, MIN_BODY_SIZE, load_gltf_body, save_gltf_body

    seed = save_gltf_body(tmp / "seed.glb", _coarse_rig(_default_rig())).read_bytes()

    def check(rig):
        v = np.asarray(rig.vertices)
        if not np.isfinite(v).all():
            return "glTF body vertices not finite"
        size = float(np.ptp(v, axis=0).max())
        if not MIN_BODY_SIZE <= size <= MAX_BODY_SIZE:
            return f"glTF body {size:.3g} m across accepted"
        if not (np.isfinite(rig.joints).all() and np.isfinite(rig.weights).all()):
            return "glTF joints or weights not finite"
        return None

    return Target("glTF / GLB", ".glb", [seed], load_gltf_body, check, mutate_gltf)


_CUBE_OBJ = b"""# seatkit subdivision cage (Catmull-Clark control mesh), metres, +Y up
# 8 vertices, 6 faces
# crease 1 2 2
# crease 2 3 1.5
v -0.2 0 -0.2
v 0.2 0 -0.2
v 0.2 0.4 -0.2
v -0.2 0.4 -0.2
v -0.2 0 0.2
v 0.2 0 0.2
v 0.2 0.4 0.2
v -0.2 0.4 0.2
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
"""

_GRID_OBJ = b"""v 0 0 0
v 0.1 0 0
v 0.2 0 0
v 0 0 0.1
v 0.1 0.05 0.1
v 0.2 0 0.1
v 0 0 0.2
v 0.1 0 0.2
v 0.2 0 0.2
f 1/1/1 4/4/4 5/5/5 2/2/2
f 2 5 6 3
f -6 -3 -2 -5
f 5 8 9 6
"""


def _cage_target(name: str, suffix: str, seeds: list, read: Callable, mutator: Callable) -> Target:
    """A cage reader, then the cage's level-1 limit surface and normals (what subdivide computes)."""
    from seatkit.export.meshes import MAX_CAGE_COORDINATE
    from seatkit.subdivision import build_operators

    def load(path):
        cage = read(path)
        ops = build_operators(cage, 1)
        return cage, ops.limit @ cage.vertices, ops.limit_normals(cage.vertices)

    def check(result):
        cage, points, normals = result
        if not _finite_in(cage.vertices, -MAX_CAGE_COORDINATE, MAX_CAGE_COORDINATE):
            return f"{name} vertices out of range accepted"
        if not (np.isfinite(points).all() and np.isfinite(normals).all()):
            return f"{name} limit surface or normals not finite"
        return None

    return Target(name, suffix, seeds, load, check, mutator)


def _obj_target(tmp: Path) -> Target:
    from seatkit.export.meshes import read_obj_cage

    return _cage_target("OBJ cage", ".obj", [_CUBE_OBJ, _GRID_OBJ], read_obj_cage, mutate)


# --------------------------------------------------------------------------- USD cages

_USD_TOKENS = (
    "[2147483647]", "[-2147483648]", "[]", "[-1]", "[0, 0]", "[1e308]", "[nan]", "[inf, 0, 0]", "(1e30, 0, 0)",
    "[(0, 0, 0)]", "@/dev/zero@", "@./other.usda@", "subLayers = [@x.usda@]", "references = @/dev/zero@",
    "int[] creaseLengths = [2147483647]", "int[] faceVertexCounts = [1000000]", "int[] faceVertexIndices = [99]",
    "float metersPerUnit = 1e30", "double metersPerUnit = 0", "matrix4d xformOp:transform = ((1e300,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1))",
    'uniform token interpolateBoundary = "none"', 'uniform token orientation = "leftHanded"', "string[]", "token", "4",
)


def _usd_seeds(tmp: Path) -> list[bytes]:
    """Two small cages written by usd-core: a cube with creases and corners, an L-shaped open grid."""
    from pxr import Usd, UsdGeom, Vt

    seeds = []
    cube_v = [(-0.2, 0, -0.2), (0.2, 0, -0.2), (0.2, 0.4, -0.2), (-0.2, 0.4, -0.2), (-0.2, 0, 0.2), (0.2, 0, 0.2), (0.2, 0.4, 0.2), (-0.2, 0.4, 0.2)]
    cube_f = [0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7]
    grid_v = [(x * 0.1, 0.05 if (x, z) == (1, 1) else 0.0, z * 0.1) for z in range(3) for x in range(3)]
    grid_f = [0, 3, 4, 1, 1, 4, 5, 2, 3, 6, 7, 4]
    for k, (points, counts, indices, creases) in enumerate(
        [(cube_v, [4] * 6, cube_f, ([0, 1, 2, 3], [2, 2], [2.0, 1.5])), (grid_v[:8], [4, 4, 4], grid_f, ([0, 1, 2], [3], [10.0, 1.0]))]
    ):
        stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageMetersPerUnit(stage, 1.0 if k == 0 else 0.01)
        UsdGeom.Xform.Define(stage, "/seatkit")
        mesh = UsdGeom.Mesh.Define(stage, "/seatkit/Cage")
        mesh.CreatePointsAttr(Vt.Vec3fArray(points))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(indices))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark)
        mesh.CreateCreaseIndicesAttr(Vt.IntArray(creases[0]))
        mesh.CreateCreaseLengthsAttr(Vt.IntArray(creases[1]))
        mesh.CreateCreaseSharpnessesAttr(Vt.FloatArray(creases[2]))
        mesh.CreateCornerIndicesAttr(Vt.IntArray([0]))
        mesh.CreateCornerSharpnessesAttr(Vt.FloatArray([3.0]))
        path = tmp / f"seed{k}.usda"
        tmp.mkdir(parents=True, exist_ok=True)
        stage.GetRootLayer().Export(str(path))
        seeds.append(path.read_bytes())
    return seeds


def mutate_usd(data: bytes, r: Chooser) -> bytes:
    """1 or 2 mutations of a .usda: a number replaced (by NaN, huge, negative, fractional ones),
    a USD token or array spliced in or put in place of a word, or a text mutation."""
    import re

    for _ in range(1 + r.randrange(2)):
        kind = r.randrange(4)
        if kind in (0, 1):  # a number in an array or value becomes an interesting one: the syntax stays valid
            first_line = data.find(b"\n")  # not the "#usda 1.0" header
            spans = [m.span() for m in re.finditer(rb"(?<![A-Za-z_])-?[0-9][0-9.eE+-]*", data) if m.start() > first_line]
            if spans:
                a, b = _pick(r, spans)
                data = data[:a] + _pick(r, INTERESTING_NUMBERS + ("2147483647", "-2147483648", "100", "3")).encode() + data[b:]
        elif kind == 2:
            data = _text_mutation(data, r, yaml=False)
        else:
            token = _pick(r, _USD_TOKENS).encode()
            data = _replace_token(data, r, token) if r.randrange(2) else _splice(data, r, token)
    return data


def _usd_target(tmp: Path) -> Target:
    from seatkit.export.usd import read_usd_cage

    return _cage_target("USD cage", ".usda", _usd_seeds(Path(tmp)), read_usd_cage, mutate_usd)


# --------------------------------------------------------------------------- .npz files (rigs, designs)

_JSON_TEXTS = (
    "", "[", "1", "[]", "null", '"x"', '{"sex": 3}', '{"sex": []}', '{"sex": "other"}', "[" * 100_000 + "]" * 100_000,
    '{"a": ' * 5000 + "1" + "}" * 5000, '{"sex": "female"}', "NaN", '{"x": 1e400}',
)


def _npz_bytes(arrays: dict) -> bytes:
    import io

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _load_npz_seed(data: bytes) -> dict:
    import io

    with np.load(io.BytesIO(data), allow_pickle=False) as f:
        return {k: f[k] for k in f.files}


def _edit_array(a: np.ndarray, r: Chooser) -> np.ndarray:
    """One edit of an array: scaled, a NaN or huge entry, reshaped, truncated, retyped, emptied."""
    kind = r.randrange(9)
    if kind == 0 and a.dtype.kind in "iuf":
        return a * _pick(r, (0, -1, 100, 1000, 1e-3, 1e30, 2**40))
    if kind == 1 and a.size and a.dtype.kind in "iuf":
        b = a.astype(np.float64 if a.dtype.kind == "f" else np.int64).copy().reshape(-1)
        b[r.randrange(b.size)] = _pick(r, (np.nan, np.inf, -1, 1e308, 2**62, -(2**62))) if a.dtype.kind == "f" else _pick(r, (-1, 2**31, 2**62, 10**6))
        return b.reshape(a.shape)
    if kind == 2 and a.size:
        return a.reshape(-1)
    if kind == 3 and len(a):
        return a[: r.randrange(len(a))]
    if kind == 4:
        return a.astype(_pick(r, (np.float32, np.int8, np.uint64, np.bool_, np.complex64, "U3", "S2", np.float16)))
    if kind == 5:
        return np.zeros((0,) + a.shape[1:], a.dtype)
    if kind == 6 and a.ndim == 2:
        return a.T
    if kind == 7 and a.size:
        return np.concatenate([a, a])
    return np.array(_pick(r, ("x", 3, np.nan, [1, 2])))


def mutate_npz(data: bytes, r: Chooser, *, json_key: str | None = None) -> bytes:
    """An .npz with 1 to 3 edits of its arrays (deleted, scaled, NaN, retyped, reshaped; the JSON of
    ``json_key`` edited as glTF's is), or (one time in five) byte-level mutations of the zip."""
    if r.randrange(5) == 0:
        return mutate(data, r, n=1 + r.randrange(2))
    arrays = _load_npz_seed(data)
    for _ in range(1 + r.randrange(3)):
        key = _pick(r, sorted(arrays))
        kind = r.randrange(6)
        if kind == 0:
            del arrays[key]
            if not arrays:
                arrays["x"] = np.zeros(1)
        elif kind == 1 and key in (json_key, "meta"):
            text = bytes(arrays[key]).decode() if key == json_key else str(arrays[key])
            try:
                doc = json.loads(text)
                _edit_json(doc, r)
                text = json.dumps(doc, allow_nan=True)
            except (TypeError, KeyError, IndexError, AttributeError, ValueError):
                text = _pick(r, _JSON_TEXTS)
            if r.randrange(4) == 0:
                text = _pick(r, _JSON_TEXTS)
            arrays[key] = np.frombuffer(text.encode(), np.uint8) if key == json_key else np.array(text)
        elif kind == 2:
            arrays[f"{key.split('_')[0]}_region_{_pick(r, ('x', 'face', '../x'))}"] = np.array(_pick(r, ([0, 1], [-1], [10**9], [])), np.int64)
        else:
            try:
                with np.errstate(all="ignore"):
                    arrays[key] = _edit_array(arrays[key], r)
            except (ValueError, TypeError, OverflowError):
                pass  # a cast this array cannot take (text to numbers)
    out = _npz_bytes(arrays)
    if r.randrange(6) == 0:  # a damaged .npy header or zip record inside
        out = mutate(out, r, n=1)
    return out


def _check_body(vertices, joints, what: str) -> str | None:
    from seatkit.constants import BODY_SIZE_RANGE

    v = np.asarray(vertices)
    if not np.isfinite(v).all():
        return f"{what} vertices not finite"
    size = float(np.ptp(v, axis=0).max())
    if not BODY_SIZE_RANGE[0] <= size <= BODY_SIZE_RANGE[1]:
        return f"{what} of {size:.3g} m accepted"
    j = np.asarray(joints)
    if not (np.isfinite(j).all() and (j >= v.min(0) - size).all() and (j <= v.max(0) + size).all()):
        return f"{what} joints far outside the body accepted"
    return None


def _rig_target(tmp: Path) -> Target:
    from seatkit.body.rig import load_rig_file, save_rig

    tmp = Path(tmp)
    rig = _coarse_rig(_default_rig())
    seed = save_rig(rig, tmp / "seed.npz").read_bytes()

    def check(rig):
        wrong = _check_body(rig.vertices, np.concatenate([rig.joints, rig.tips]), "npz body")
        if wrong:
            return wrong
        if not (np.isfinite(rig.weights).all() and np.allclose(rig.weights.sum(axis=1), 1)):
            return "npz body weights not normalised"
        return None

    return Target("npz rig", ".npz", [seed], load_rig_file, check, mutate_npz)


def _design_seed(tmp: Path) -> bytes:
    """A design.npz of the coarse default body seated in a small cage (no build needed)."""
    from seatkit.body import load_pose
    from seatkit.body.skinning import pose_rig
    from seatkit.model import BuildResult, ControlMesh
    from seatkit.recipe import default_recipe
    from seatkit.state import save_design

    body = pose_rig(_coarse_rig(_default_rig()), load_pose("upright-sitting"))
    xs = np.linspace(-0.3, 0.3, 4)
    vertices = np.array([[x, 0.45, z] for z in xs for x in xs])
    faces = np.array([[j * 4 + i, (j + 1) * 4 + i, (j + 1) * 4 + i + 1, j * 4 + i + 1] for j in range(3) for i in range(3)])
    mesh = ControlMesh(
        vertices, faces, np.full(len(faces), 1), face_person=np.zeros(len(faces), np.int64),
        crease_edges=np.array([[0, 1]]), crease_sharpness=np.array([2.0]), corners=np.array([0]),
        corner_sharpness=np.array([4.0]), meta={"special_cases": []}, face_labels=tuple(f"f{i}" for i in range(len(faces))),
    )
    recipe = default_recipe()
    result = BuildResult(recipe=recipe, bodies=[body], pressures=[], control_mesh=mesh, initial_mesh=mesh)
    return save_design(result, Path(tmp) / "design.npz").read_bytes()


def _design_target(tmp: Path) -> Target:
    from seatkit.designs import load_checked_design
    from seatkit.export.meshes import MAX_CAGE_COORDINATE

    def check(result):
        recipe, bodies, mesh, initial = result
        for b in bodies:
            wrong = _check_body(b.vertices, np.concatenate([b.joints, b.tips, b.segment_com]), "design body")
            if wrong:
                return wrong
        for m in (mesh, initial):
            if m is not None and not _finite_in(m.vertices, -MAX_CAGE_COORDINATE, MAX_CAGE_COORDINATE):
                return "design cage vertices out of range accepted"
        return _check_recipe_result(recipe)

    return Target(
        "design.npz", ".npz", [_design_seed(Path(tmp))], load_checked_design, check,
        lambda d, r: mutate_npz(d, r, json_key="header"),
    )


# --------------------------------------------------------------------------- batch tables, name maps

_CSV_TABLE = b"""name,pose,body,mass,template
small,upright-sitting,default-female,55,chair
tall,lounger,default-male,95,
pose-file,poses/my.yaml,,80.5,bench
"""

_YAML_TABLE = b"""items:
  - {name: small, pose: upright-sitting, body: default-female, mass: 55}
  - {pose: lounger, body: default-male, mass: 95.5, template: bench}
  - name: 7
    pose: ../poses/x.bvh
"""


def _batch_target(tmp: Path, suffix: str) -> Target:
    from seatkit.batch import TABLE_MASS_RANGE, collect_items

    out = Path(tmp) / "out"

    def load(path):
        return collect_items([path], out=out)

    def check(items):
        for it in items:
            for body in it.recipe["bodies"]:
                mass = (body.get("params") or {}).get("mass")
                if mass is not None and not _finite_in([mass], *TABLE_MASS_RANGE):
                    return f"table mass {mass!r} accepted"
            if not isinstance(it.recipe["template"], str) or not it.name or len(it.name) > 255:
                return "table template or name not text"
        return None

    seed = _CSV_TABLE if suffix == ".csv" else _YAML_TABLE
    name = "batch table CSV" if suffix == ".csv" else "batch table YAML"
    return Target(name, suffix, [seed], load, check, lambda d, r: mutate(d, r, yaml=suffix != ".csv"))


def _name_map_target(tmp: Path) -> Target:
    from seatkit.body.name_maps import load_name_map
    from seatkit.resources import data_path
    from seatkit.skeleton import SEGMENT_INDEX

    seeds = [p.read_bytes() for p in sorted(data_path("name_maps").glob("*.yaml"))]
    names = ["Hips", "Spine", "Spine1", "Neck", "Head", "LeftUpLeg", "LeftLeg", "LeftFoot", "mixamorig:Hips", "lButtock", "RightArm"]

    def load(path):
        m = load_name_map(path)
        return m, m.resolve(names)

    def check(result):
        m, (index, score) = result
        if not set(m.segments) <= set(SEGMENT_INDEX):
            return "name map with unknown segments accepted"
        return None

    return Target("name map", ".yaml", seeds, load, check, lambda d, r: mutate(d, r, yaml=True))


#: Name -> builder of every target (built lazily: the glTF seed needs a body).
TARGET_BUILDERS = {
    "recipe": _recipe_target,
    "template": _template_target,
    "pose": _pose_target,
    "bvh": _bvh_target,
    "gltf": _gltf_target,
    "obj": _obj_target,
    "usd": _usd_target,
    "rig": _rig_target,
    "design": _design_target,
    "batch-csv": lambda tmp: _batch_target(tmp, ".csv"),
    "batch-yaml": lambda tmp: _batch_target(tmp, ".yaml"),
    "name-map": _name_map_target,
}


def make_target(name: str, tmp: Path) -> Target:
    """The :class:`Target` ``name`` (a key of :data:`TARGET_BUILDERS`), seeds written under ``tmp``."""
    return TARGET_BUILDERS[name](Path(tmp))


# --------------------------------------------------------------------------- running


class Hang(Exception):
    """A case ran past its time limit."""


@dataclass
class Outcome:
    """What one case did: ``kind`` is ok, accepted, crash or hang."""

    kind: str
    signature: str = ""
    detail: str = ""
    seconds: float = 0.0


def _signature(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    mine = [f for f in frames if "/seatkit/" in f.filename.replace("\\", "/") and not f.filename.endswith("fuzzing.py")]
    where = f"{Path(mine[-1].filename).name}:{mine[-1].name}" if mine else "?"
    return f"{type(exc).__name__} in {where}"


def message_problem(message: str, path: Path) -> str | None:
    """Why an error message is not one bounded line naming the file (None if it is)."""
    if "\n" in message or "\r" in message:
        return "message spans several lines"
    if len(message) > MAX_MESSAGE:
        return f"message of {len(message)} characters"
    if path.name not in message:
        return "message does not name the file"
    return None


def run_case(target: Target, data: bytes, path: Path, *, timeout: float = 10.0) -> Outcome:
    """Write ``data`` to ``path``, load it with ``target`` and classify the outcome."""
    path.write_bytes(data)
    use_alarm = hasattr(signal, "setitimer")
    if use_alarm:

        def on_alarm(signum, frame):
            raise Hang()

        previous = signal.signal(signal.SIGALRM, on_alarm)
        signal.setitimer(signal.ITIMER_REAL, timeout)
    t0 = time.perf_counter()
    try:
        try:
            result = target.load(path)
        finally:
            if use_alarm:
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, previous)
    except Hang:
        return Outcome("hang", "hang", f"over {timeout:g} s", time.perf_counter() - t0)
    except SeatkitError as e:
        dt = time.perf_counter() - t0
        problem = message_problem(str(e), path)
        if problem:
            return Outcome("crash", f"{type(e).__name__}: {problem}", str(e)[:300], dt)
        return Outcome("ok", type(e).__name__, str(e), dt)
    except (Exception, RecursionError, MemoryError) as e:  # noqa: BLE001 - classifying is the point
        return Outcome("crash", _signature(e), f"{type(e).__name__}: {str(e)[:300]}", time.perf_counter() - t0)
    dt = time.perf_counter() - t0
    if dt > timeout:
        return Outcome("hang", "hang", f"{dt:.1f} s", dt)
    try:
        wrong = target.check(result)
    except Exception as e:  # noqa: BLE001 - an accepted result the oracle cannot even read is wrong
        return Outcome("crash", f"accepted but unreadable: {_signature(e)}", f"{type(e).__name__}: {str(e)[:300]}", dt)
    if wrong:
        return Outcome("crash", f"accepted but wrong: {wrong.split(' ')[0]} {wrong.split(' ')[-1]}", wrong, dt)
    return Outcome("accepted", "", "", dt)


@dataclass
class Tally:
    """Counts of one loader's run."""

    name: str
    cases: int = 0
    ok: int = 0
    accepted: int = 0
    crashes: int = 0
    hangs: int = 0
    seconds: float = 0.0
    slowest: float = 0.0
    signatures: dict = field(default_factory=dict)  # signature -> (count, first detail, input)

    def add(self, outcome: Outcome, data: bytes) -> None:
        self.cases += 1
        self.seconds += outcome.seconds
        self.slowest = max(self.slowest, outcome.seconds)
        if outcome.kind in ("crash", "hang"):
            if outcome.kind == "crash":
                self.crashes += 1
            else:
                self.hangs += 1
            count, detail, example = self.signatures.get(outcome.signature, (0, outcome.detail, data))
            self.signatures[outcome.signature] = (count + 1, detail, example)
        elif outcome.kind == "ok":
            self.ok += 1
        else:
            self.accepted += 1


def fuzz(target: Target, cases: int, workdir: Path, *, seed: int = 0, timeout: float = 10.0, progress=None) -> Tally:
    """Run ``cases`` mutated inputs through ``target``; every input is reproducible from ``seed``."""
    tally = Tally(target.name)
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    path = workdir / f"case{target.suffix}"
    for k in range(cases):
        r = random.Random(f"{seed}:{target.name}:{k}")
        data = target.mutate(target.seeds[r.randrange(len(target.seeds))], r)
        tally.add(run_case(target, data, path, timeout=timeout), data)
        if progress is not None:
            progress(k + 1, tally)
    return tally
