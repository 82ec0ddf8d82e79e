"""Faults injected into ``seatkit build``: kill -9, races, unwritable folders, a full disk.

Each case runs the real command line in a subprocess where a process has to
die (``kill -9`` is the process killing itself with SIGKILL at a chosen
moment, so the test does not depend on timing), or in process where only an
OS error has to be raised.
"""

from __future__ import annotations

import errno
import json
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from seatkit.cli import app
from seatkit.output import leftovers

pytestmark = pytest.mark.slow

#: A quick build: the chair with its full export (the faults are in the writing).
ARGS = ["build", "--template", "chair", "--no-refiners", "-q"]


def _run_cli(script: str, out: Path, *extra: str, helpers: str = "") -> subprocess.CompletedProcess:
    """Run ``seatkit build ... --out out`` in a fresh interpreter after ``script`` (the fault).

    ``helpers``: ``SEATKIT_HELPERS`` (``on``: the helper processes whatever
    the machine's load, for the faults that concern them).
    """
    argv = ["seatkit", *ARGS, "--out", str(out), *extra]
    code = textwrap.dedent(script) + f"\nimport sys\nfrom seatkit.cli import main\nsys.argv = {argv!r}\nmain()\n"
    env = {**os.environ, "SEATKIT_DISABLE_PLUGIN_AUTOLOAD": "1", "SEATKIT_HELPERS": helpers}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie waiting to be reaped counts as ended)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] not in ("Z", "X")


def _run_id(folder: Path) -> str:
    return json.loads((folder / ".seatkit-run").read_text())["run"]


def _error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.strip()]


@pytest.fixture(scope="module")
def previous(tmp_path_factory) -> Path:
    """A finished build, copied into each test's folder as the 'previous output'."""
    out = tmp_path_factory.mktemp("previous") / "X"
    done = _run_cli("", out)
    assert done.returncode == 0, done.stderr
    return out


def _copy_previous(previous: Path, out: Path) -> None:
    import shutil

    shutil.copytree(previous, out)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers end with a killed build on Linux only")
def test_kill_9_during_the_export_children_end_and_the_next_build_cleans_up(tmp_path, previous):
    out = tmp_path / "X"
    _copy_previous(previous, out)
    before = _run_id(out)
    # the build kills itself with SIGKILL once the export worker runs and the
    # staging folder exists, after printing the worker's process id
    killed = _run_cli(
        """
        import contextlib, os, signal
        import seatkit.pipeline as pl
        def write(result, exporters, registry, timer, *, overwrite, helper=None, spare=None, early=None, designed=None):
            # the staging folder the design's files went into before the evaluation, else a new one
            staged = designed.staging if designed is not None else None
            with contextlib.nullcontext() if staged else pl.staging_folder(pl.output_target(result.recipe), overwrite=overwrite):
                print(*(h.pid() for h in (helper, spare) if h), flush=True)
                os.kill(os.getpid(), signal.SIGKILL)
        pl._write = write
        """,
        out,
        helpers="on",
    )
    assert killed.returncode == -signal.SIGKILL
    children = [int(p) for p in killed.stdout.split()]
    assert children, "the build had no export worker to outlive it"
    deadline = time.monotonic() + 10
    while any(_alive(p) for p in children) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(p) for p in children), "a child process outlived the killed build"
    staging, old = leftovers(out)
    assert len(staging) == 1 and not old  # the fault as reported: a staging folder left behind
    assert _run_id(out) == before  # the previous output intact

    again = _run_cli("", out)
    assert again.returncode == 0, again.stderr
    assert leftovers(out) == ([], [])
    assert not (tmp_path / ".X.lock").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["X"]
    assert (out / "cage.usda").exists() and _run_id(out)


def test_kill_9_between_the_two_renames_the_previous_output_is_restored(tmp_path, previous):
    out = tmp_path / "X"
    _copy_previous(previous, out)
    before = _run_id(out)
    killed = _run_cli(
        """
        import os, signal
        import seatkit.output as output  # the staging folder's renames (seatkit.output.finish_output)
        class _Os:
            def __getattr__(self, name):
                return getattr(os, name)
            def replace(self, src, dst):
                if ".staging-" in str(src):  # the second rename: the previous output is already moved away
                    os.kill(os.getpid(), signal.SIGKILL)
                return os.replace(src, dst)
        output.os = _Os()
        """,
        out,
    )
    assert killed.returncode == -signal.SIGKILL
    staging, old = leftovers(out)
    assert not out.exists() and len(old) == 1 and len(staging) == 1  # the fault as reported
    assert _run_id(old[0] / "X") == before

    # the next build into X fails (an unsupported pose) after taking the folder:
    # the previous output is back in X and the leftovers are gone
    failed = _run_cli("", out, "--pose", "feet-tucked")
    assert failed.returncode == 1
    assert _run_id(out) == before
    assert leftovers(out) == ([], [])


def test_a_build_into_a_folder_another_build_holds_is_refused_at_once(tmp_path):
    from seatkit.output import claim_output

    out = tmp_path / "X"
    with claim_output(out):
        start = time.monotonic()
        second = _run_cli("", out)
        seconds = time.monotonic() - start
    assert second.returncode == 1
    (line,) = _error_lines(second.stderr)
    assert line == (
        f"seatkit: error: another seatkit build (process {os.getpid()}) is writing the output folder {out}; "
        "wait for it to finish or choose another --out"
    )
    assert not out.exists()
    assert seconds < 60  # refused before the design (which takes seconds), not after it


def test_two_builds_racing_for_one_folder_one_wins_and_the_other_says_so(tmp_path):
    out = tmp_path / "X"
    argv = [sys.executable, "-m", "seatkit.cli", *ARGS, "--out", str(out)]
    env = {**os.environ, "SEATKIT_DISABLE_PLUGIN_AUTOLOAD": "1"}
    procs = [subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env) for _ in range(2)]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
    for p in procs:
        p.stdout.close()
        p.stderr.close()
    codes = sorted(code for code, _ in results)
    if codes == [0, 0]:
        pytest.skip("the two builds did not overlap (one finished before the other started)")
    assert codes == [0, 1]
    (line,) = _error_lines(next(err for code, err in results if code == 1))
    assert line.startswith("seatkit: error: another seatkit build (process ")
    assert f"is writing the output folder {out}" in line
    assert (out / ".seatkit-run").exists() and leftovers(out) == ([], [])


# ------------------------------------------------------------------ permissions


def _unprivileged(fn):
    """Run ``fn()`` as a user without special rights; its (ok, value) pickled back.

    Root ignores permission bits, so under root the work runs in a forked
    child that has dropped to ``nobody`` (every module it needs is imported
    before the fork).
    """
    if os.geteuid() != 0:
        try:
            return True, fn()
        except Exception as exc:  # noqa: BLE001 - compared by the test
            return False, exc
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        try:
            os.close(r)
            os.setgid(65534)
            os.setuid(65534)
            import seatkit

            if not os.access(Path(seatkit.__file__).parent, os.R_OK | os.X_OK):
                # an interpreter or install that only root may read (a venv
                # in a private temporary folder): nobody cannot run a build
                answer = (None, "seatkit's installation is not readable by an unprivileged user")
            else:
                try:
                    answer = (True, fn())
                except Exception as exc:  # noqa: BLE001
                    answer = (False, exc)
            with os.fdopen(w, "wb") as pipe:
                pipe.write(pickle.dumps(answer))
        finally:
            os._exit(0)
    os.close(w)
    with os.fdopen(r, "rb") as pipe:
        data = pipe.read()
    os.waitpid(pid, 0)
    ok, value = pickle.loads(data)
    if ok is None:
        pytest.skip(value)
    return ok, value


@pytest.fixture
def open_tmp():
    """A temporary folder every user may enter (pytest's tmp_path is private to its owner)."""
    import shutil

    path = Path(tempfile.mkdtemp(prefix="seatkit-perm-"))
    path.chmod(0o777)
    yield path
    for p in [path, *path.rglob("*")]:
        if p.is_dir():
            p.chmod(0o755)
    shutil.rmtree(path)


def _build_unprivileged(out: Path, monkeypatch):
    """A build into ``out`` by an unprivileged user: the error, and whether the design was computed."""
    import seatkit.pipeline as pl
    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import apply_overrides, default_recipe

    recipe = apply_overrides(default_recipe(), template="chair", refiners=[], output=str(out))
    pm = get_plugin_manager()
    pm.registry  # noqa: B018 - loaded before dropping rights

    def design(*args, **kw):
        raise AssertionError("the design was computed before the folder was checked")

    monkeypatch.setattr(pl, "_design", design)
    import jsonschema  # noqa: F401 - imported before dropping rights (a recipe mapping is checked against its schema)
    import threadpoolctl  # noqa: F401 - imported before dropping rights

    import seatkit.output  # noqa: F401
    from seatkit.body import list_poses

    list_poses()
    return _unprivileged(lambda: pl.build(recipe, pm=pm, processes=False))


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork to drop root rights")
def test_a_read_only_output_folder_is_refused_before_the_design(open_tmp, monkeypatch):
    out = open_tmp / "X"
    out.mkdir()
    (out / ".seatkit-run").write_text("{}")
    out.chmod(0o555)
    ok, error = _build_unprivileged(out, monkeypatch)
    assert not ok
    assert type(error).__name__ == "OutputError", repr(error)
    assert str(error) == (
        f"cannot replace the output folder {out}: it is read-only (no write permission); "
        "make it writable or choose another --out"
    )


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork to drop root rights")
def test_a_folder_without_write_permission_is_refused_before_the_design(open_tmp, monkeypatch):
    parent = open_tmp / "locked"
    parent.mkdir()
    parent.chmod(0o555)
    out = parent / "X"
    ok, error = _build_unprivileged(out, monkeypatch)
    assert not ok
    assert type(error).__name__ == "OutputError", repr(error)
    assert str(error) == f"cannot write the output folder {out}: no permission to write into {parent}"
    assert "\n" not in str(error)
    nested = parent / "sub" / "X"  # a folder that cannot be created
    ok, error = _build_unprivileged(nested, monkeypatch)
    assert not ok and str(error).startswith(f"cannot create the output folder {nested}: Permission denied")
    assert list(parent.iterdir()) == []


def test_a_full_disk_is_one_line_naming_the_folder_and_leaves_nothing(tmp_path, monkeypatch, previous):
    out = tmp_path / "X"
    _copy_previous(previous, out)
    before = _run_id(out)
    real_fsync = os.fsync
    calls = []

    def full(fd):
        calls.append(fd)
        if len(calls) > 2:  # a few files fit, then the disk is full
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_fsync(fd)

    monkeypatch.setattr(os, "fsync", full)
    result = CliRunner().invoke(app, [*ARGS, "--out", str(out)])
    assert result.exit_code == 1, result.output
    (line,) = _error_lines(result.stderr)
    assert line == f"seatkit: error: cannot write the output folder {out}: No space left on device"
    assert _run_id(out) == before  # the previous output intact
    assert leftovers(out) == ([], [])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["X"]
