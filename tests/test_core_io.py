"""Atomic writes and output folders."""

import pytest

from seatkit.errors import SeatkitError
from seatkit.io import atomic_path, atomic_write, is_complete, mark_complete


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_write(target, "w") as fh:
            fh.write("half")
            raise RuntimeError("interrupted")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_atomic_path_keeps_suffix_and_renames(tmp_path):
    target = tmp_path / "mesh.stl"
    with atomic_path(target) as tmp:
        assert tmp.suffix == ".stl" and tmp != target
        tmp.write_bytes(b"solid")
    assert target.read_bytes() == b"solid"
    assert len(list(tmp_path.iterdir())) == 1


def _staged(tmp_path, name, files):
    staging = tmp_path / name
    staging.mkdir()
    for f in files:
        (staging / f).write_text(f)
    return staging


def test_output_dir_is_not_mixed(tmp_path):
    from seatkit.output import finish_output as _finish_output

    d = tmp_path / "run"
    first = _staged(tmp_path, ".a", ["cage.obj", "old-only.txt"])
    mark_complete(first, run_id="a", files={"cage": first / "cage.obj"})
    _finish_output(first, d, overwrite=False)
    assert is_complete(d)
    (d / "cage.obj").unlink()
    assert not is_complete(d)  # a listed file is missing: not a valid run
    # a previous seatkit run is replaced as a whole: nothing of it is left
    second = _staged(tmp_path, ".b", ["cage.obj"])
    mark_complete(second, run_id="b", files={"cage": second / "cage.obj"})
    _finish_output(second, d, overwrite=False)
    assert sorted(p.name for p in d.iterdir()) == [".seatkit-run", "cage.obj"]
    # a folder with files seatkit did not write is refused, unless --overwrite
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep")
    with pytest.raises(SeatkitError, match="did not write"):
        _finish_output(_staged(tmp_path, ".c", ["cage.obj"]), foreign, overwrite=False)
    assert (foreign / "notes.txt").read_text() == "keep"
    _finish_output(_staged(tmp_path, ".d", ["cage.obj"]), foreign, overwrite=True)
    assert not (foreign / "notes.txt").exists() and (foreign / "cage.obj").exists()
