"""One test per crash class, hang and silently wrong acceptance that fuzzing the
loaders found (issue 20): each input now ends in seatkit's own error, on one
line that names the file and stays short, or is refused before any stage can
misuse it. ``tests/test_fuzz_loaders.py`` searches for new ones."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from seatkit.body import load_pose, load_rig
from seatkit.body.bvh import MAX_JOINTS, load_bvh, read_bvh, write_bvh
from seatkit.body.gltf import load_gltf_body, save_gltf_body
from seatkit.body.poses import load_pose_file
from seatkit.cli import app
from seatkit.errors import InputError, RecipeError, SeatkitError
from seatkit.export.meshes import read_obj_cage
from seatkit.fuzzing import MAX_MESSAGE, alias_bomb, chain_bvh, join_glb, message_problem, split_glb
from seatkit.plugins import get_plugin_manager
from seatkit.recipe import apply_overrides, check_recipe, load_recipe
from seatkit.template.engine import load_template
from seatkit.template.schema import read_template, resolve_parameters
from seatkit.yamlio import MAX_DEPTH, parse_yaml

runner = CliRunner()


def refused(call, path, pattern, kind=SeatkitError):
    """``call()`` raises ``kind`` on one bounded line naming ``path`` and matching ``pattern``."""
    with pytest.raises(kind, match=pattern or None) as err:
        call()
    assert message_problem(str(err.value), path) is None, str(err.value)[:300]
    return str(err.value)


def write(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return path


# --------------------------------------------------------------------------- YAML layer

# a 393-byte recipe took 25.7 s and 2.5 GB; this one (522 bytes) would build 9**10 values
ALIAS_BOMB = alias_bomb(10, 9)


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("template: &r {x: *r}\n", r":1: alias \*r refers to a value that contains it"),  # was RecursionError
        ("bodies: &r [*r]\n", r"alias \*r refers to a value that contains it"),
        (ALIAS_BOMB, r"grows past 50000 values once its aliases .* are expanded"),  # was a 25 s hang
        ("template: " + "[" * 5000 + "]" * 5000 + "\n", rf"nested more than {MAX_DEPTH} levels deep"),  # RecursionError
        ("template: chair\nseed: !!timestamp 2001-02-30\n", r":2: cannot read the value '2001-02-30' tagged !!timestamp"),  # was a date
        ("template: chair\nseed: !!timestamp\n", r":2: cannot read the value '' tagged !!timestamp"),  # was AttributeError
        ("template: chair\nseed: !!set {a}\n", r":2: a mapping tagged !!set"),
        ("seed: " + "9" * 5000 + "\n", r":1: cannot read the value '9999.*\(5002 characters\) as int: Exceeds the limit"),
        ("template: !!python/object:os.system x\n", r"cannot read the value 'x' tagged !!python/object:os.system"),
        ("template: chair\nbodies: [{model: x}]\nx: *nowhere\n", r":3: not valid YAML: found undefined alias"),
        ("? [a, b]\n: 1\n", r":1: \(top level\): mapping keys must be plain names"),
        ("template: chair\x00\n", r":1: not valid YAML: character U\+0000 is not allowed"),  # was ReaderError
    ],
)
def test_hostile_yaml_is_refused_on_one_line(tmp_path, text, pattern):
    path = write(tmp_path, "r.yaml", text)
    refused(lambda: load_recipe(path), path, pattern, RecipeError)
    refused(lambda: read_template(path), path, pattern, RecipeError)
    # the pose reader builds values lazily: a bad value may come after an unknown key
    structural = "alias" in pattern or "nested" in pattern or "valid YAML" in pattern
    refused(lambda: load_pose_file(path), path, pattern if structural else "", RecipeError)


@pytest.mark.parametrize("bad", [b"\xff", b"\xc3(", b"\x80"])
def test_non_utf8_text_is_named_with_its_byte_offset(tmp_path, bad):
    data = b"template: chair\nname: caf" + bad + b"\n"
    offset = data.index(bad)
    path = write(tmp_path, "r.yaml", data)
    for load in (load_recipe, read_template, load_pose_file):  # was UnicodeDecodeError / ReaderError
        msg = refused(lambda: load(path), path, r"not UTF-8 text", RecipeError)
        assert f"{path}:2: not UTF-8 text: byte 0x{bad[0]:02x} at byte offset {offset}" in msg


def test_long_values_are_not_echoed_in_full(tmp_path):
    huge = "x" * 2_000_000
    for text in (f"template: chair\nbodies: [{{pose: 3, model: {huge}}}]\n", f"template: chair\n{huge}: 1\n", f"seed: '{huge}'\n"):
        path = write(tmp_path, "r.yaml", text)
        msg = refused(lambda: load_recipe(path), path, r"", RecipeError)
        assert len(msg) <= MAX_MESSAGE


def test_several_problems_are_one_line_with_a_count(tmp_path):
    path = write(tmp_path, "r.yaml", "seed: -1\nsurface_level: 9\nmu: 3\n")  # (mu belongs under pressure)
    msg = refused(lambda: load_recipe(path), path, r"", RecipeError)
    assert msg.startswith(f"{path}:1: seed: expected a value >= 0, got -1") and msg.endswith("(and 2 more problems)")


# --------------------------------------------------------------------------- recipe numbers


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("pressure: {mu: .inf}\n", r":2: pressure.mu: expected a finite number, got inf"),  # ValueError in qp.py
        ("pressure: {mu: .nan}\n", r"pressure.mu: expected a finite number, got nan"),
        ("pressure: {mu: 1e6}\n", r"pressure.mu: expected a value <= 10"),
        ("pressure: {lambda: 1.0e+308}\n", r"pressure.lambda: expected a value <= 1000000.0, got 1e\+308"),  # was LinAlgError
        ("pressure: {lambda: .nan}\n", r"pressure.lambda"),
        ("bodies: [{frame: 1.0}]\n", r"bodies\[0\].frame: expected a whole number \(no decimal point\), got 1.0"),
        ("seed: 1.0\n", r":2: seed: expected a whole number \(no decimal point\), got 1.0"),
        ("seed: true\n", r"seed: expected a whole number, got True"),
        ("seed: 99999999999999999999999\n", r"seed: expected a number of at most"),
        ("surface_level: 3.0\n", r"surface_level: expected a whole number"),
        ("bodies: [{offset: [0, .nan, 0]}]\n", r"bodies\[0\].offset\[1\]: expected a finite number, got nan"),  # "contact set is empty"
        ("bodies: [{offset: [1.0e+17, 0, 0]}]\n", r"bodies\[0\].offset\[0\]: expected a value <= 10"),
        ("evaluate: {support_distance: .nan}\n", r"evaluate.support_distance: expected a finite number"),  # "unsupported"
        ("evaluate: {support_distance: .inf}\n", r"evaluate.support_distance: expected a finite number"),  # all contact
        ("evaluate: {enabled: 'false'}\n", r"evaluate.enabled: expected true or false, got 'false'"),
        ("placement: {gap: .inf}\n", r"placement.gap: expected a finite number"),
    ],
)
def test_recipe_numbers_are_finite_real_and_physical(tmp_path, text, pattern):
    path = write(tmp_path, "r.yaml", "template: chair\n" + text)
    refused(lambda: load_recipe(path), path, pattern, RecipeError)


def test_lambda_inf_still_means_rigid(tmp_path):
    for text in ("pressure: {lambda: inf}\n", "pressure: {lambda: .inf}\n"):
        recipe, _ = load_recipe(write(tmp_path, "r.yaml", text))
        assert recipe["pressure"]["lambda"] == math.inf


@pytest.fixture(scope="module")
def registry():
    return get_plugin_manager().registry


@pytest.mark.parametrize(
    ("flags", "pattern"),
    [
        ({"mu": math.inf}, r"pressure.mu: expected a friction coefficient between 0 and 10, got inf"),
        ({"mu": math.nan}, r"pressure.mu: expected a friction coefficient"),
        ({"lam": 1e308}, r"pressure.lambda: expected a number from 1e-9 to 1e6, or inf, got 1e\+308"),
        ({"lam": 1e-320}, r"pressure.lambda: expected a number from 1e-9 to 1e6"),
        ({"lam": -1.0}, r"pressure.lambda"),
        ({"seed": -3}, r"seed: expected a whole number between 0 and 4294967295"),
        ({"frame": 10**9}, r"bodies\[0\].frame: expected a frame number"),
    ],
)
def test_flags_are_checked_like_the_file(registry, flags, pattern):
    recipe = apply_overrides(load_recipe(None)[0], **flags)
    with pytest.raises(RecipeError, match=pattern):
        check_recipe(recipe, registry)


def test_body_mass_overflow_is_a_recipe_error(registry, tmp_path):
    path = write(tmp_path, "r.yaml", "template: chair\nbodies: [{params: {mass: " + "9" * 400 + "}}]\n")
    recipe, doc = load_recipe(path)
    refused(lambda: check_recipe(recipe, registry, document=doc), path, r"bodies\[0\].params.mass: expected a body mass", RecipeError)


@pytest.mark.parametrize(
    ("value", "pattern"),
    [
        ("1.0e+12", r"expected a whole number \(no decimal point\), got 1000000000000.0"),  # was MemoryError
        ("1000000000000", r"expected a value <= 20000"),
        ("2.5", r"expected a whole number, got 2.5"),  # was silently 2
    ],
)
def test_ransac_iterations_must_be_a_sane_whole_number(tmp_path, value, pattern):
    text = (tmp_path.parent / "chair.yaml") if False else None  # noqa: F841
    from seatkit.resources import template_path

    chair = template_path("chair.yaml").read_text()
    path = write(tmp_path, "t.yaml", chair.replace("ransac_iterations: 300", f"ransac_iterations: {value}"))
    refused(lambda: read_template(path), path, rf"parameters.ransac_iterations: {pattern}", RecipeError)


@pytest.mark.parametrize("value", [1.0e12, 2.5, math.nan, -1, True])
def test_template_params_overrides_are_checked(value):
    spec = load_template(__import__("seatkit.resources", fromlist=["x"]).template_path("chair.yaml")).spec
    with pytest.raises(RecipeError, match=r"ransac_iterations: expected a whole number from 1 to 20000"):
        resolve_parameters(spec, {"ransac_iterations": value})
    with pytest.raises(RecipeError, match=r"support_distance: expected a number from 0 to 1 \(m\)"):
        resolve_parameters(spec, {"support_distance": math.inf if value != -1 else -1})


# --------------------------------------------------------------------------- poses


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("root:\n  translation: [1.0e+17, 0, 0]\n", r":2: root.translation\[0\]: expected a number of metres from -100 to 100"),
        ("root:\n  translation: [0, 0, 1.0e+30]\n", r"root.translation\[2\]"),
        ("joints:\n  RightLeg: {x: " + "9" * 400 + "}\n", r"joints.RightLeg.x: expected an angle in degrees"),  # OverflowError
        ("joints:\n  RightLeg: {x: .nan}\n", r"joints.RightLeg.x: expected an angle in degrees"),
        ("joints:\n  RightLeg: {x: !!binary '???'}\n", r":2: cannot read the value '\?\?\?' tagged !!binary"),  # ConstructorError
        ("joints:\n  RightLeg: {x: 2001-02-30}\n", r":2: joints.RightLeg.x: expected an angle in degrees from -720 to 720, got '2001-02-30'"),
        ("joints: !!timestamp\n", r":1: cannot read the value '' tagged !!timestamp"),  # was AttributeError in PyYAML
        ("joints: !!timestamp {}\n", r":1: a mapping tagged !!timestamp"),
        ("joints: !!float\n", r":1: cannot read the value '' as float"),  # was IndexError in PyYAML
        ("joints:\n  ? [a]\n  : 1\n", r":2: joints: keys must be plain names, got a list"),  # AttributeError
        ("joints: &j {RightLeg: *j}\n", r"alias \*j refers to a value that contains it"),  # RecursionError
        ("base: " + "a" * 5000 + ".yaml\n", r":1: base: no pose file 'aaa.*characters\) beside"),  # OSError: name too long
        ("supported: 'false'\n", r"supported: expected true or false, got 'false'"),
    ],
)
def test_pose_files(tmp_path, text, pattern):
    path = write(tmp_path, "p.yaml", text)
    refused(lambda: load_pose_file(path), path, pattern, RecipeError)


# --------------------------------------------------------------------------- BVH


@pytest.fixture(scope="module")
def rig():
    return load_rig("default-male")


@pytest.fixture(scope="module")
def bvh_text(rig, tmp_path_factory):
    path = write_bvh(tmp_path_factory.mktemp("bvh") / "seed.bvh", [load_pose("upright-sitting")], rig)
    return path.read_text()


def test_huge_joint_chain_is_refused_quickly(tmp_path):
    path = write(tmp_path, "chain.bvh", chain_bvh(100_000))  # 84 s of quadratic parsing before
    refused(lambda: read_bvh(path), path, rf":\d+: more than {MAX_JOINTS} joints; not a human skeleton", InputError)


def test_long_chain_within_the_limit_parses(tmp_path):
    motion = read_bvh(write(tmp_path, "chain.bvh", chain_bvh(MAX_JOINTS)))
    assert len(motion.names) == MAX_JOINTS
    assert motion.parents.tolist() == list(range(-1, MAX_JOINTS - 1))
    assert motion.rest_positions()[-1].tolist() == [0.0, MAX_JOINTS - 1.0, 0.0]


def _edit_offset(text: str, joint: str, xyz: str) -> str:
    lines = text.splitlines()
    k = next(i for i, l in enumerate(lines) if l.split()[-1:] == [joint] and l.split()[0] in ("ROOT", "JOINT"))
    j = next(i for i in range(k, len(lines)) if lines[i].strip().startswith("OFFSET"))
    lines[j] = "  OFFSET " + xyz
    return "\n".join(lines) + "\n"


def test_degenerate_hips_are_refused(rig, bvh_text, tmp_path):
    # both hip joints at the hips' origin: the left-right axis (and SVD) was undefined
    text = _edit_offset(_edit_offset(bvh_text, "LeftUpLeg", "0 0 0"), "RightUpLeg", "0 0 0")
    path = write(tmp_path, "flat.bvh", text)
    refused(lambda: load_bvh(path, rig=rig), path, r"degenerate skeleton: the left and right hip joints coincide", InputError)


@pytest.mark.parametrize(
    ("old", "new", "pattern"),
    [
        ("CHANNELS 3", "CHANNELS -5", r"CHANNELS: expected a channel count from 0 to 6, got '-5'"),  # loops backwards
        ("CHANNELS 3", "CHANNELS 9999999999", r"CHANNELS: expected a channel count from 0 to 6"),
        ("Frame Time:", "Frame Time: nan\nX:", r"Frame Time: expected a finite number"),
    ],
)
def test_malformed_bvh_headers(bvh_text, tmp_path, old, new, pattern):
    path = write(tmp_path, "bad.bvh", bvh_text.replace(old, new, 1))
    refused(lambda: read_bvh(path), path, pattern, InputError)


def test_bvh_huge_values_and_bad_bytes(rig, bvh_text, tmp_path):
    path = write(tmp_path, "big.bvh", _edit_offset(bvh_text, "LeftUpLeg", "1e300 0 0"))
    refused(lambda: read_bvh(path), path, r"OFFSET 1e300 0 0: larger than 1e\+06 file units", InputError)
    lines = bvh_text.splitlines()
    lines[-1] = "1e300 " + " ".join(lines[-1].split()[1:])
    path = write(tmp_path, "motion.bvh", "\n".join(lines) + "\n")
    refused(lambda: read_bvh(path), path, r"frame 0, channel 1: 1e300 is beyond", InputError)
    path = write(tmp_path, "latin1.bvh", bvh_text.replace("Hips", "H\xe9ps").encode("latin-1"))
    refused(lambda: read_bvh(path), path, r"not UTF-8 text: byte 0xe9", InputError)


# --------------------------------------------------------------------------- glTF


@pytest.fixture(scope="module")
def glb(rig, tmp_path_factory):
    return save_gltf_body(tmp_path_factory.mktemp("glb") / "seed.glb", rig).read_bytes()


def _edited(glb: bytes, edit) -> bytes:
    doc, blob = split_glb(glb)
    edit(doc)
    return join_glb(doc, blob)


def _first_child_node(doc):
    return next(n for n in doc["nodes"] if n.get("children"))


@pytest.mark.parametrize(
    ("edit", "pattern"),
    [
        (lambda d: _first_child_node(d).__setitem__("children", [-1]), r"nodes\[\d+\].children: expected a whole number from 0"),
        (lambda d: _first_child_node(d).__setitem__("children", [10**6]), r"nodes\[\d+\].children: expected a whole number"),
        (lambda d: _first_child_node(d).__setitem__("children", ["x"]), r"not a readable glTF/GLB file \(ValueError: invalid literal"),
        (lambda d: d["nodes"][_first_child_node(d)["children"][0]].__setitem__("children", [d["nodes"].index(_first_child_node(d))]),
         r"is a child of both|has a cycle"),
        (lambda d: d["accessors"][0].__setitem__("count", 10**7), r"accessors\[0\]: reads \d+ bytes of bufferViews\[0\]"),
        (lambda d: d["accessors"][0].__setitem__("count", -1), r"accessors\[0\].count: expected a whole number"),
        (lambda d: d["accessors"][0].__setitem__("bufferView", 99), r"accessors\[0\].bufferView: expected a whole number"),
        (lambda d: d["accessors"][0].__setitem__("componentType", 5130), r"unsupported componentType/type 5130/'VEC3'"),
        (lambda d: d["bufferViews"][0].__setitem__("byteStride", 1), r"bufferViews\[0\].byteStride: expected a multiple of 4 from 12 to 252"),
        (lambda d: d["bufferViews"][0].__setitem__("byteLength", 10**9), r"bufferViews\[0\]: bytes 0..1000000000 are beyond buffer 0"),
        (lambda d: d["meshes"].__setitem__(0, None), r"not a readable glTF/GLB file \(AttributeError"),
        (lambda d: d["buffers"][0].__setitem__("uri", "/etc/passwd"), r"buffers\[0\].uri '/etc/passwd': expected a file name beside"),
        # found by the 10,000-case run: JOINTS_0 of 4 components with WEIGHTS_0 of 3 (an IndexError)
        (lambda d: d["accessors"][d["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"]].__setitem__("type", "VEC3"),
         r"JOINTS_0 has 4 components per vertex but WEIGHTS_0 3"),
        # _local_matrix: a zero quaternion, a short matrix, a NaN translation
        (lambda d: d["nodes"][0].__setitem__("rotation", [0, 0, 0, 0]), r"nodes\[0\].rotation: a zero quaternion is not a rotation"),
        (lambda d: d["nodes"][0].__setitem__("matrix", [1.0] * 15), r"nodes\[0\].matrix: expected 16 numbers"),
        (lambda d: d["nodes"][0].__setitem__("translation", [float("nan"), 0, 0]), r"nodes\[0\].translation: expected 3 numbers"),
    ],
)
def test_malformed_gltf_structure(glb, tmp_path, edit, pattern):
    path = write(tmp_path, "bad.glb", _edited(glb, edit))
    refused(lambda: load_gltf_body(path), path, pattern, InputError)


def _scale_root(doc, factor):
    roots = set(range(len(doc["nodes"]))) - {c for n in doc["nodes"] for c in n.get("children", [])}
    for r in roots:
        doc["nodes"][r]["scale"] = [factor] * 3


@pytest.mark.parametrize(("factor", "pattern"), [(1000.0, r"the skinned body is 1.\d+e\+03 m across; expected a person from 0.3 to 3 m"),
                                                  (0.001, r"the skinned body is 0.00\d+ m across"),
                                                  (1e308, r"nodes\[\d+\].scale: expected 3 numbers of magnitude at most 10000, got \[1e\+308")])
def test_gltf_bodies_are_human_size(glb, tmp_path, factor, pattern):
    path = write(tmp_path, "huge.glb", _edited(glb, lambda d: _scale_root(d, factor)))
    refused(lambda: load_gltf_body(path), path, pattern, InputError)


def test_unedited_glb_still_loads(glb, tmp_path):
    body = load_gltf_body(write(tmp_path, "ok.glb", _edited(glb, lambda d: None)))
    assert 1.5 < np.ptp(body.vertices, axis=0).max() < 2.2


# --------------------------------------------------------------------------- OBJ cage

CUBE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"


@pytest.mark.parametrize(
    ("old", "new", "pattern"),
    [
        ("v 1 0 0\n", "v 1e308 0 0\n", r":2: vertex 2: coordinates must be finite and within \+-100000"),  # wrote vn 0 0 0
        ("v 1 0 0\n", "v nan 0 0\n", r":2: vertex 2: coordinates must be finite"),
        ("v 1 0 0\n", "v 1\n", r":2: malformed OBJ record 'v 1'"),  # ValueError
        ("f 1 4 3 2\n", "f 99999999999999999999999 4 3 2\n", r":9: face 1: vertex indices must be"),  # TypeError
        ("f 1 4 3 2\n", "f 0 4 3 2\n", r":9: face 1: vertex indices must be"),
        # found by the 10,000-case run: an OverflowError in Cage
        ("v 0 0 0\n", "# crease 2 99999999999999999999999 1.5\nv 0 0 0\n", r":1: crease: expected two vertex numbers 1..n"),
        ("v 0 0 0\n", "# crease 1 2 nan\nv 0 0 0\n", r":1: crease: expected two vertex numbers 1..n and a sharpness >= 0"),
    ],
)
def test_obj_cage(tmp_path, old, new, pattern):
    path = write(tmp_path, "c.obj", CUBE.replace(old, new, 1))
    refused(lambda: read_obj_cage(path), path, pattern, InputError)
    assert read_obj_cage(write(tmp_path, "ok.obj", CUBE)).n_faces == 6


# --------------------------------------------------------------------------- through the CLI


def _one_line_error(result, path_text: str):
    assert result.exit_code == 1, result.output
    lines = [l for l in result.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("seatkit: error: "), result.stderr[:500]
    assert "Traceback" not in result.output and path_text in lines[0] and len(lines[0]) <= MAX_MESSAGE + 20


def test_cli_hostile_inputs_end_in_one_line(tmp_path, bvh_text, glb):
    out = str(tmp_path / "out")
    cases = [
        (["build", "--template", "chair", "--mu", "inf", "--out", out], "pressure.mu"),
        (["build", "--template", "chair", "--lambda", "1e308", "--out", out], "pressure.lambda"),
        (["build", "--recipe", str(write(tmp_path, "bomb.yaml", ALIAS_BOMB)), "--out", out], "bomb.yaml"),
        (["build", "--recipe", str(write(tmp_path, "utf.yaml", b"template: \xff\n")), "--out", out], "utf.yaml"),
        (["build", "--recipe", str(write(tmp_path, "seed.yaml", "template: chair\nseed: 1.0\n")), "--out", out], "seed.yaml"),
        (["build", "--template", "chair", "--pose", str(write(tmp_path, "far.yaml", "root: {translation: [1e17, 0, 0]}\n")), "--out", out], "far.yaml"),
        (["build", "--template", "chair", "--pose", str(write(tmp_path, "chain.bvh", chain_bvh(2000))), "--out", out], "chain.bvh"),
        (["build", "--template", "chair", "--body", str(write(tmp_path, "big.glb", _edited(glb, lambda d: _scale_root(d, 1000.0)))), "--out", out], "big.glb"),
        (["subdivide", str(write(tmp_path, "c.obj", CUBE.replace("v 1 0 0", "v 1e308 0 0"))), "--out", str(tmp_path / "s.obj")], "c.obj"),
    ]
    for args, named in cases:
        _one_line_error(runner.invoke(app, args), named)
    assert not (tmp_path / "out").exists() and not (tmp_path / "s.obj").exists()


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ('bodies: [{pose: "a\\0.yaml"}]\n', r"bodies\[0\].pose: 'a\\x00.yaml' contains a NUL character"),  # ValueError
        ("bodies: [{pose: " + "a" * 5000 + ".yaml}]\n", r"bodies\[0\].pose: expected at most 4096 characters, got 5005"),
        ("bodies: [{params: {path: " + "a" * 300 + ".glb}}]\n", r"bodies\[0\].params.path: file not found"),  # OSError
        ('bodies: [{params: {path: "x\\0.glb"}}]\n', r"bodies\[0\].params.path: file not found"),  # ValueError
        ("bodies: [{params: {path: 3}}]\n", r"bodies\[0\].params.path: file not found: 3"),  # TypeError in normalisation
        ("bodies: [{pose: " + "a" * 300 + ".yaml}]\n", r"bodies\[0\].pose: pose file not found"),  # OSError
    ],
)
def test_recipe_paths_the_os_refuses(registry, tmp_path, text, pattern):
    path = write(tmp_path, "r.yaml", "template: chair\n" + text)

    def load_and_check():
        recipe, doc = load_recipe(path)
        check_recipe(recipe, registry, document=doc)

    refused(load_and_check, path, pattern, RecipeError)


@pytest.mark.parametrize(("lam", "mu"), [(1e-9, 0.0), (1e6, 10.0), (math.inf, 10.0), (1e-9, 10.0)])
def test_the_ends_of_the_recipe_ranges_still_solve(lam, mu):
    """Every lambda and mu the recipe accepts gives reactions that carry the weight
    (``lambda: 1e308`` was a LinAlgError and ``mu: .inf`` a ValueError in the solver)."""
    from seatkit.constants import GRAVITY
    from seatkit.pressure import solve_pressure
    from seatkit.pressure.synthetic import seated_capsule_body
    from seatkit.recipe import LIMITS

    assert LIMITS["lambda"][:2] == (1e-9, 1e6) and LIMITS["mu"][:2] == (0.0, 10.0)
    body = seated_capsule_body(resolution=1)
    field = solve_pressure(body, exclude=[], lam=lam, mu=mu)
    weight = body.segment_mass.sum() * GRAVITY
    total = field.force.sum(axis=0)
    assert abs(total[1] - weight) / weight < 1e-6
    assert np.abs(total[[0, 2]]).max() / weight < 1e-6


def test_long_names_in_templates_are_not_echoed_in_full(tmp_path):
    from seatkit.resources import template_path

    chair = template_path("chair.yaml").read_text()
    for old, new in [("rows: [foot, shank, thigh]", "rows: [" + "a" * 5000 + "]"),
                     ("columns: [right, left]", "columns: [" + "x" * 5000 + "]"),
                     ("rows: [foot, shank, thigh]", "rows: [{mass: " + "9" * 400 + "}]"),
                     ("min_distance: 0.02", "m" * 5000 + ": 0.02")]:
        path = write(tmp_path, "t.yaml", chair.replace(old, new, 1))
        msg = refused(lambda: load_template(path), path, r"", RecipeError)
        assert len(msg) <= MAX_MESSAGE
