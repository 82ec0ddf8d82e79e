"""One test per crash class, hang and silently wrong acceptance of issue 30:
the readers docs/robustness.md did not list (USD cages, .npz rigs, design.npz,
batch tables), base: chains, FIFOs and devices, size caps, refinement sizes
and message lengths. Each input now ends in seatkit's own error on one line
of at most 500 characters that names the file, through the CLI without a
traceback. ``tests/test_fuzz_loaders.py`` searches for new ones."""

from __future__ import annotations

import json
import os
import signal
import time

import numpy as np
import pytest
from typer.testing import CliRunner

from seatkit.batch import collect_items
from seatkit.body import load_rig
from seatkit.body.bvh import read_bvh
from seatkit.body.poses import MAX_BASE_DEPTH, load_pose_file
from seatkit.body.rig import load_rig_file, save_rig
from seatkit.cli import app
from seatkit.errors import InputError, RecipeError, SeatkitError
from seatkit.export.usd import read_usd_cage
from seatkit.fuzzing import MAX_MESSAGE, _design_seed, _usd_seeds, message_problem
from seatkit.recipe import load_recipe
from seatkit.commands.evaluate import load_checked_design

runner = CliRunner()


def refused(call, path, pattern, kind=SeatkitError):
    """``call()`` raises ``kind`` on one bounded line naming ``path`` and matching ``pattern``."""
    with pytest.raises(kind, match=pattern) as err:
        call()
    assert message_problem(str(err.value), path) is None, str(err.value)[:300]
    return str(err.value)


def one_line_error(result, named: str):
    """A CLI result: exit 1, one line ``seatkit: error: ...`` of at most 500 characters naming ``named``."""
    assert result.exit_code == 1, result.output
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("seatkit: error: "), result.stderr[:600]
    message = lines[0][len("seatkit: error: ") :]
    assert "Traceback" not in result.output and named in message and len(message) <= MAX_MESSAGE
    return message


@pytest.fixture
def no_hang():
    """Fail (not hang) a test that blocks for more than 10 s."""

    def on_alarm(signum, frame):
        raise TimeoutError("blocked for 10 s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(10)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


# --------------------------------------------------------------------------- USD cages


@pytest.fixture(scope="module")
def usda(tmp_path_factory):
    """The text of a valid cube cage with creases and corners."""
    return _usd_seeds(tmp_path_factory.mktemp("usd"))[0].decode()


def test_the_usd_seed_reads(usda, tmp_path):
    path = tmp_path / "c.usda"
    path.write_text(usda)
    cage = read_usd_cage(path)
    assert cage.vertices.shape == (8, 3) and len(cage.crease_edges) == 2 and cage.corners.tolist() == [0]


@pytest.mark.parametrize(
    ("edit", "pattern"),
    [
        # a 2**31-step Python loop that grew to 13 GB: now the lengths must sum to the indices
        (("creaseLengths = [2, 2]", "creaseLengths = [2147483647]"), r"creaseLengths: expected chains of at least 2 vertices summing to the 4"),
        (("creaseLengths = [2, 2]", "creaseLengths = [-3, 7]"), r"creaseLengths: expected chains"),
        (("creaseIndices = [0, 1, 2, 3]", "creaseIndices = [0, 1, 2, 99]"), r"creaseIndices: expected vertex indices from 0 to 7"),
        (("creaseSharpnesses = [2, 1.5]", "creaseSharpnesses = [2, 1.5, 1]"), r"creaseSharpnesses: expected 2 \(one per crease\) or 2"),
        (("faceVertexIndices = [0, 3,", "faceVertexIndices = [0, 99,"), r"faceVertexIndices: expected vertex indices from 0 to 7"),  # IndexError
        (("faceVertexCounts = [4, 4", "faceVertexCounts = [2147483647, 4"), r"faceVertexCounts\[0\]: expected a face of 3 to 64"),
        (("faceVertexCounts = [4, 4", "faceVertexCounts = [5, 4"), r"faceVertexCounts sum to 25 but there are 24 indices"),
        (("(-0.2, 0, -0.2)", "(1e30, 0, -0.2)"), r"points: coordinates in metres .* finite and within"),
        (("metersPerUnit = 1", "metersPerUnit = 1e30"), r"metersPerUnit: expected 1e-06 to 1000"),
        (("int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]", "string[] faceVertexCounts = [\"a\"]"), r"faceVertexCounts"),  # ValueError
        (("def Mesh", "def Mesh def"), r"usd-core cannot read this file: ErrorException"),  # pxr ErrorException
        (("metersPerUnit = 1", "metersPerUnit = 1\n    subLayers = [@/dev/zero@]"), r"refers to other files \(/dev/zero\); seatkit reads self-contained"),
    ],
)
def test_hostile_usd_cages_are_refused(usda, tmp_path, no_hang, edit, pattern):
    old, new = edit
    assert old in usda, old
    path = tmp_path / "c.usda"
    path.write_text(usda.replace(old, new, 1))
    t0 = time.process_time()
    refused(lambda: read_usd_cage(path), path, pattern, InputError)
    assert time.process_time() - t0 < 2.0


def test_usd_that_is_not_utf8_is_refused(usda, tmp_path):
    # usd-core's own message failed to print (UnicodeDecodeError inside Tf.ErrorException.__str__)
    path = tmp_path / "c.usda"
    path.write_bytes(usda.encode().replace(b"Cage", b"Ca\xffge", 1))
    refused(lambda: read_usd_cage(path), path, r"usd-core cannot read this file", InputError)


def test_cli_subdivide_refuses_a_hostile_usd(usda, tmp_path):
    path = tmp_path / "c.usda"
    path.write_text(usda.replace("creaseLengths = [2, 2]", "creaseLengths = [2147483647]"))
    one_line_error(runner.invoke(app, ["subdivide", str(path), "--out", str(tmp_path / "s.obj")]), "c.usda")
    assert not (tmp_path / "s.obj").exists()


def test_a_big_cage_at_level_3_is_refused_before_any_work(tmp_path):
    # 16,900 quads at level 3 make 1,081,600 quads: about 2.4 GB (11.7 GB for the cage)
    n = 130
    lines = [f"v {i * 0.01} 0 {j * 0.01}" for j in range(n + 1) for i in range(n + 1)]
    lines += [f"f {j * (n + 1) + i + 1} {(j + 1) * (n + 1) + i + 1} {(j + 1) * (n + 1) + i + 2} {j * (n + 1) + i + 2}" for j in range(n) for i in range(n)]
    path = tmp_path / "big.obj"
    path.write_text("\n".join(lines) + "\n")
    t0 = time.process_time()
    message = one_line_error(runner.invoke(app, ["subdivide", str(path), "--levels", "3", "--out", str(tmp_path / "s.obj")]), "big.obj")
    assert "16,900 faces refined 3 times makes 1,081,600 quads" in message and "at most 1,000,000" in message
    assert time.process_time() - t0 < 10 and not (tmp_path / "s.obj").exists()
    # level 2 (270,400 quads) is within the cap
    result = runner.invoke(app, ["subdivide", str(path), "--levels", "2", "--out", str(tmp_path / "s2.obj")])
    assert result.exit_code == 0, result.output


# --------------------------------------------------------------------------- .npz rigs


@pytest.fixture(scope="module")
def rig():
    return load_rig("default-male")


def _npz(path, **arrays):
    np.savez(path, **arrays)
    return path


def _rig_arrays(rig, **changes):
    arrays = dict(vertices=rig.vertices, faces=rig.faces, weights=rig.weights, joints=rig.joints, tips=rig.tips)
    arrays.update(changes)
    return {k: v for k, v in arrays.items() if v is not None}


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        ({"meta": np.array("[1, 2]")}, r"meta: expected a JSON mapping, got list"),  # AttributeError
        ({"meta": np.array("[" * 100_000 + "]" * 100_000)}, r"meta: expected a small JSON mapping"),  # RecursionError
        ({"meta": np.array([1.0, 2.0])}, r"'meta': expected one JSON text, got an array of float64"),
        ({"vertices": np.array([["a", "b", "c"]])}, r"'vertices': expected numbers, got an array of <U1"),  # ValueError
        ({"faces": np.zeros((3, 3))}, r"'faces': expected integers, got an array of float64"),
        ({"weights": np.array(3.0)}, r"weights must be \(13348, 21\)"),  # TypeError
        ({"region_x": np.array([10**9])}, r"region 'x' indexes vertices outside"),
        ({"meta": np.array('{"sex": []}')}, r"meta.sex must be 'male' or 'female', got \[\]"),
        ({"tips": None}, r"missing arrays tips"),
    ],
)
def test_hostile_rig_files_are_refused(rig, tmp_path, change, pattern):
    path = _npz(tmp_path / "r.npz", **_rig_arrays(rig, **change))
    refused(lambda: load_rig_file(path), path, pattern, InputError)


@pytest.mark.parametrize("scale", [0.0, 1e-3, 2.0, 100.0, 1e30])
def test_rig_bodies_outside_a_persons_size_are_refused(rig, tmp_path, no_hang, scale):
    # 0 m to 1e30 m were accepted: a 3.5 m person got a 0.96 m seat, a x100 body hung the build
    arrays = _rig_arrays(rig, vertices=rig.vertices * scale, joints=rig.joints * scale, tips=rig.tips * scale)
    path = _npz(tmp_path / "r.npz", **arrays)
    refused(lambda: load_rig_file(path), path, r"the body is .* m across; expected a person from 0.3 to 3 m", InputError)


def test_a_rig_joint_far_outside_the_body_is_refused(rig, tmp_path):
    joints = rig.joints.copy()
    joints[7] = [0, 1e6, 0]
    path = _npz(tmp_path / "r.npz", **_rig_arrays(rig, joints=joints))
    refused(lambda: load_rig_file(path), path, r"joints\[7\] .* lies outside the body", InputError)


def test_damaged_npz_files_are_refused(rig, tmp_path):
    good = save_rig(rig, tmp_path / "good.npz").read_bytes()
    cases = {
        "junk.npz": b"PK\x03\x04 not a zip",  # BadZipFile
        "cut.npz": good[: len(good) // 2],
        "flip.npz": good[:200] + bytes([good[200] ^ 0xFF]) + good[201:],
    }
    for name, data in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        refused(lambda: load_rig_file(path), path, r"not a seatkit body file", InputError)


def test_an_npz_whose_header_promises_more_than_it_holds_is_refused(tmp_path):
    # a .npy header claiming 2**40 floats would make numpy allocate them before reading
    import io
    import zipfile

    member = io.BytesIO()
    np.lib.format.write_array_header_1_0(member, {"descr": "<f8", "fortran_order": False, "shape": (2**40,)})
    member.write(b"\0" * 64)
    path = tmp_path / "lie.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("vertices.npy", member.getvalue())
    refused(lambda: load_rig_file(path), path, r"vertices: its header promises 1,099,511,627,776 values", InputError)


def test_cli_build_refuses_a_giant_npz_body(rig, tmp_path):
    arrays = _rig_arrays(rig, vertices=rig.vertices * 100, joints=rig.joints * 100, tips=rig.tips * 100)
    path = _npz(tmp_path / "giant.npz", **arrays)
    out = tmp_path / "out"
    one_line_error(runner.invoke(app, ["build", "--body", str(path), "--out", str(out)]), "giant.npz")
    assert not out.exists()


# --------------------------------------------------------------------------- design.npz


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    data = _design_seed(tmp_path_factory.mktemp("design"))
    import io

    with np.load(io.BytesIO(data)) as f:
        return {k: f[k] for k in f.files}


def _with_header(arrays, edit):
    header = json.loads(bytes(arrays["header"]).decode())
    edit(header)
    return {**arrays, "header": np.frombuffer(json.dumps(header).encode(), np.uint8)}


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        (lambda a: {**a, "header": np.frombuffer(b"[1]", np.uint8)}, r"header: expected a JSON mapping, got list"),  # AttributeError
        (lambda a: {**a, "header": np.array(3.0)}, r"no header: expected a 1-D uint8 array"),  # TypeError
        (lambda a: {k: v for k, v in a.items() if k != "body0_joints"}, r"missing array 'body0_joints'"),  # KeyError
        (lambda a: _with_header(a, lambda h: h["bodies"][0].pop("regions")), r"header.bodies: expected 1 to 64 mappings"),  # KeyError
        (lambda a: _with_header(a, lambda h: h["meshes"].pop("final")), r"header.meshes: expected 'final'"),
        (lambda a: _with_header(a, lambda h: h.update(format=2)), r"design format 2, this seatkit reads 1"),
        (lambda a: _with_header(a, lambda h: h["recipe"].update(surface_level=40)), r"header.recipe:.*surface_level"),
        (lambda a: {**a, "body0_vertices": a["body0_vertices"] * 100}, r"body 0: the body is .* m across"),
        (lambda a: {**a, "final_faces": a["final_faces"] + 1000}, r"final cage: cage face 0 refers to vertex"),
        (lambda a: {**a, "final_face_person": a["final_face_person"] + 5}, r"final_face_person: expected person numbers from -1 to 0"),
        (lambda a: {**a, "final_vertices": np.full_like(a["final_vertices"], np.nan)}, r"final_vertices: expected finite numbers"),
    ],
)
def test_hostile_design_files_are_refused(design, tmp_path, change, pattern):
    path = _npz(tmp_path / "design.npz", **change(design))
    refused(lambda: load_checked_design(path), path, pattern, InputError)


def test_a_design_recipe_with_keys_left_out_is_read_normalised(design, tmp_path):
    # the 10,000-case run found it: a recipe of only a template passed the schema, and
    # evaluate would have read recipe["pressure"] from it (KeyError)
    path = _npz(tmp_path / "design.npz", **_with_header(design, lambda h: h.update(recipe={"template": "chair"})))
    recipe = load_checked_design(path)[0]
    assert recipe["template"] == "chair" and recipe["pressure"]["mu"] == 0.5 and recipe["surface_level"] == 3


def test_cli_evaluate_refuses_a_hostile_design(design, tmp_path):
    _npz(tmp_path / "design.npz", **{**design, "header": np.frombuffer(b"[1]", np.uint8)})
    one_line_error(runner.invoke(app, ["evaluate", str(tmp_path)]), "design.npz")
    assert not (tmp_path / "evaluation.json").exists()


# --------------------------------------------------------------------------- batch tables


@pytest.mark.parametrize(
    ("name", "text", "pattern"),
    [
        ("t.csv", "pose,mass\nupright-sitting,heavy\n", r"t.csv:2: row 1: mass: expected a body mass in kg from 20 to 300, got 'heavy'"),  # ValueError
        ("t.csv", "pose,mass\nupright-sitting,1e30\n", r"mass: expected a body mass in kg from 20 to 300"),
        ("t.csv", "pose,mass\nupright-sitting,nan\n", r"mass: expected a body mass in kg"),
        ("t.csv", "pose,colour\nupright-sitting,red\n", r"t.csv:2: row 1: unknown column 'colour'; expected pose, body, mass, template, name"),
        ("t.csv", 'pose\n"' + "a" * 200_000 + '"\n', r"t.csv:.*not a readable CSV table: field larger than field limit"),  # csv.Error
        ("t.yaml", "items:\n  - {pose: [a, b]}\n", r"t.yaml:2: row 1: pose: expected text, got \['a', 'b'\]"),  # TypeError
        ("t.yaml", "items:\n  - {pose: upright-sitting, name: {a: 1}}\n", r"row 1: name: expected text"),  # TypeError
        ("t.yaml", "items:\n  - {pose: upright-sitting, template: 3}\n", r"row 1: template: expected text, got 3"),  # TypeError
        ("t.yaml", "items:\n  - {pose: upright-sitting, mass: true}\n", r"row 1: mass: expected a body mass in kg from 20 to 300, got True"),
        ("t.yaml", "items:\n  - {pose: upright-sitting, body: 'default-male:height'}\n", r"t.yaml:2: row 1: --body 'default-male:height'"),
        ("t.yaml", "items: 3\n", r"t.yaml:1: items: expected a list of mappings"),
    ],
)
def test_hostile_batch_tables_are_refused(tmp_path, name, text, pattern):
    path = tmp_path / name
    path.write_text(text)
    refused(lambda: collect_items([path], out=tmp_path / "o"), path, pattern, RecipeError)


def test_a_batch_table_that_is_not_utf8_is_refused(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes(b"pose,mass\nupright-sitting,\xff\n")  # UnicodeDecodeError
    refused(lambda: collect_items([path], out=tmp_path / "o"), path, r"t.csv:2: not UTF-8 text: byte 0xff", RecipeError)


def test_cli_batch_refuses_a_hostile_table(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("pose,mass\nupright-sitting,heavy\n")
    one_line_error(runner.invoke(app, ["batch", str(path), "--out", str(tmp_path / "o")]), "t.csv")


# --------------------------------------------------------------------------- pose chains, FIFOs, devices, caps


def test_a_chain_of_1000_base_poses_is_refused_in_one_line(tmp_path):
    # was RecursionError
    for i in range(1000):
        (tmp_path / f"p{i}.yaml").write_text(f"base: p{i + 1}.yaml\n")
    (tmp_path / "p1000.yaml").write_text("base: upright-sitting\n")
    message = refused(lambda: load_pose_file(tmp_path / "p0.yaml"), tmp_path / "p15.yaml", r"a chain of more than 16 pose files")
    assert "p0.yaml -> ... -> p15.yaml -> p16.yaml" in message
    # a chain within the limit loads, and ends at the library pose
    deep = MAX_BASE_DEPTH - 1
    assert load_pose_file(tmp_path / f"p{1000 - deep + 1}.yaml").angles.shape == load_pose_file(tmp_path / "p1000.yaml").angles.shape


def test_a_cycle_of_base_poses_is_named(tmp_path):
    (tmp_path / "a.yaml").write_text("base: b.yaml\n")
    (tmp_path / "b.yaml").write_text("base: c.yaml\n")
    (tmp_path / "c.yaml").write_text("base: b.yaml\n")
    refused(lambda: load_pose_file(tmp_path / "a.yaml"), tmp_path / "c.yaml", r"cycle of base poses \(b -> c -> b\)")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this OS")
def test_fifos_are_refused_without_blocking(tmp_path, no_hang):
    # a FIFO given as a pose, BVH or recipe blocked forever
    loaders = {
        "p.yaml": lambda p: load_pose_file(p),
        "m.bvh": lambda p: read_bvh(p),
        "r.yaml": lambda p: load_recipe(p),
        "b.npz": lambda p: load_rig_file(p),
        "c.usda": lambda p: read_usd_cage(p),
        "t.csv": lambda p: collect_items([p], out=tmp_path / "o"),
    }
    for name, load in loaders.items():
        path = tmp_path / name
        os.mkfifo(path)
        with pytest.raises(SeatkitError) as err:
            load(path)
        assert name in str(err.value) and ("FIFO" in str(err.value) or "no such file" in str(err.value)), str(err.value)
    fifo_dir = tmp_path / "batch"
    fifo_dir.mkdir()
    os.mkfifo(fifo_dir / "x.yaml")  # a FIFO in a batch folder is not opened to see if it is a table
    collect_items([fifo_dir], out=tmp_path / "o")
    one_line_error(runner.invoke(app, ["build", "--recipe", str(tmp_path / "r.yaml"), "--out", str(tmp_path / "out")]), "r.yaml")


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
def test_a_symlink_to_a_device_is_refused(tmp_path, no_hang):
    # a .bvh symlink to /dev/zero was read without a size cap
    for name, load in {"z.bvh": read_bvh, "z.yaml": load_pose_file, "z.npz": load_rig_file, "z.usda": read_usd_cage}.items():
        path = tmp_path / name
        path.symlink_to("/dev/zero")
        refused(lambda: load(path), path, r"is a character device, expected a", SeatkitError)


def test_files_past_their_cap_are_refused_before_reading(tmp_path, monkeypatch):
    from seatkit import io as seatkit_io

    path = tmp_path / "big.bvh"
    path.write_bytes(b"HIERARCHY\n" + b" " * 2000)
    monkeypatch.setitem(seatkit_io.MAX_FILE_BYTES, "BVH", 1000)
    refused(lambda: read_bvh(path), path, r"2,010 bytes, larger than the 0 MB seatkit reads for a BVH file", InputError)


# --------------------------------------------------------------------------- message length


def test_every_error_message_is_one_bounded_line():
    long = "x.usda: faceVertexIndices " + " ".join(str(i) for i in range(3000)) + ": expected indices below 8"
    for error in (InputError(long), RecipeError(long.replace(" ", "\n", 3))):
        message = str(error)
        assert len(message) <= MAX_MESSAGE and "\n" not in message
        # the start (file, field) and the end (what was expected) are kept, whole words only
        assert message.startswith("x.usda: faceVertexIndices 0 1 2") and message.endswith("2999: expected indices below 8")
        assert "characters left out" in message
        head = message.split(" ... (")[0]
        assert all(word.isdigit() or word in ("x.usda:", "faceVertexIndices") for word in head.split())


def test_the_cli_prints_a_long_error_as_one_bounded_line(tmp_path):
    # a path of 2,000 characters in a message: the promise is 500
    deep = tmp_path.joinpath(*(["d" * 200] * 10))
    message = one_line_error(runner.invoke(app, ["subdivide", str(deep / "c.obj"), "--out", str(tmp_path / "s.obj")]), "c.obj")
    assert "characters left out" in message and message.endswith("c.obj: no such cage file")
