"""Atomic writes and output folders."""

import pytest

from seatkit.errors import SeatkitError
from seatkit.io import atomic_path, atomic_write, is_complete, mark_complete, prepare_output_dir


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


def test_output_dir_is_not_mixed(tmp_path):
    d = tmp_path / "run"
    prepare_output_dir(d, run_id="a")
    (d / "cage.obj").write_text("v 0 0 0\n")
    assert not is_complete(d)
    mark_complete(d, run_id="a", files={"cage": d / "cage.obj"})
    assert is_complete(d)
    with pytest.raises(SeatkitError, match="not empty"):
        prepare_output_dir(d, run_id="b")
    prepare_output_dir(d, run_id="b", overwrite=True)
    assert not (d / "cage.obj").exists()
    (d / "cage.obj").unlink(missing_ok=True)
