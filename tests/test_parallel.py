"""Background work in a forked child process: values, errors, clean-up, and the build's results with and without it."""

from __future__ import annotations

import json
import os
import pickle
import re
import time
from pathlib import Path

import numpy as np
import pytest

import seatkit
from seatkit.errors import MissingExtraError, SeatkitError, UnsupportedPoseError
from seatkit.parallel import Background, can_fork

needs_fork = pytest.mark.skipif(not can_fork(), reason="forked workers run on Linux only")


def _all_children() -> set[tuple[int, str]]:
    """(pid, state) of this process's children, zombies included (Linux /proc)."""
    me, out = os.getpid(), set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        fields = text[text.rindex(")") + 2 :].split()
        if int(fields[1]) == me:
            out.add((int(stat.parent.name), fields[0]))
    return out


_BEFORE: set = set()


@pytest.fixture(autouse=True)
def _note_children():
    """Children that other tests of the session left (a Dask cluster...) are not ours."""
    _BEFORE.clear()
    _BEFORE.update(pid for pid, _ in _all_children())


def _children() -> list[tuple[int, str]]:
    """Children started (and not reaped) since the test began."""
    return sorted(c for c in _all_children() if c[0] not in _BEFORE)


def _square_pid(x):
    return x * x, os.getpid()


def _raise(exc):
    raise exc


class _Unpicklable(SeatkitError):
    def __init__(self, message):
        super().__init__(message)
        self.hook = lambda: None  # a lambda cannot be pickled


@needs_fork
def test_value_comes_back_from_another_process_and_the_child_is_reaped():
    work = Background(_square_pid, np.arange(4.0), name="square")
    value, pid = work.result()
    np.testing.assert_array_equal(value, np.arange(4.0) ** 2)
    assert pid != os.getpid()
    assert _children() == []
    assert work.result()[1] == pid  # asking again gives the same answer


def test_thread_fallback_gives_the_same_value():
    work = Background(_square_pid, np.arange(4.0), name="square", process=False)
    value, pid = work.result()
    np.testing.assert_array_equal(value, np.arange(4.0) ** 2)
    assert pid == os.getpid()


@pytest.mark.parametrize("process", [True, False])
def test_a_seatkit_error_keeps_its_type_message_and_attributes(process):
    err = UnsupportedPoseError("the knees cannot be supported", parts=["LeftShin"], diagnostics={"faces": 3})
    with pytest.raises(UnsupportedPoseError, match="the knees cannot be supported") as info:
        Background(_raise, err, name="baseline", process=process).result()
    assert info.value.parts == ["LeftShin"]
    assert info.value.diagnostics == {"faces": 3}
    if process and can_fork():
        assert any("raised in the baseline process" in n for n in info.value.__notes__)
    assert _children() == []


@needs_fork
def test_an_error_that_cannot_be_pickled_still_arrives_as_a_seatkit_error():
    with pytest.raises(SeatkitError, match="no picklable error"):
        Background(_raise, _Unpicklable("no picklable error"), name="x").result()


def test_missing_extra_error_survives_pickling():
    err = pickle.loads(pickle.dumps(MissingExtraError("dask[distributed]", "batch")))
    assert (err.package, err.extra) == ("dask[distributed]", "batch")
    assert "pip install 'seatkit[batch]'" in str(err)


@needs_fork
def test_a_child_that_dies_is_reported_not_waited_for_forever():
    # one clear error (a SeatkitError: the CLI prints one line, no traceback)
    with pytest.raises(SeatkitError, match="the crash process exited with status 3"):
        Background(os._exit, 3, name="crash").result()
    assert _children() == []


@needs_fork
def test_close_stops_and_reaps_a_child_that_is_still_running():
    work = Background(time.sleep, 30.0, name="sleeper")
    assert len(_children()) == 1
    start = time.perf_counter()
    work.close()
    assert time.perf_counter() - start < 5.0
    assert _children() == []


# ------------------------------------------------------------------ inside a build

RECIPE = {
    "template": "chair",
    "refiners": [],
    "exporters": [],
    "evaluate": {"enabled": True, "baseline": "flat-patch"},
}


@needs_fork
def test_build_gives_the_same_results_with_the_baseline_in_a_process_or_on_a_thread():
    a = seatkit.build(dict(RECIPE), write=False, processes=True)
    b = seatkit.build(dict(RECIPE), write=False, processes=False)
    assert a.metrics == b.metrics
    assert a.metrics["baseline"][0]["supported"] is True
    for key in ("control_mesh", "surface"):
        np.testing.assert_array_equal(a.extra["baseline"][key].vertices, b.extra["baseline"][key].vertices)
    assert _children() == []


class _BrokenBaseline:
    name = "broken-baseline"
    description = "a baseline template that cannot fit"

    def fit(self, bodies, pressures, *, params=None, seed=0):
        raise UnsupportedPoseError("the broken baseline cannot fit this pose", parts=["Hips"])

    def bind(self, steps):
        return self

    def check_params(self, params):
        return None


class _Exploding:
    name = "explode"
    description = "a refiner that fails"

    def refine(self, mesh, bodies, pressures, *, params=None):
        raise SeatkitError("the refiner exploded")


class _TestPlugin:
    @seatkit.hookimpl
    def seatkit_register_templates(self):
        return [_BrokenBaseline()]

    @seatkit.hookimpl
    def seatkit_register_refiners(self):
        return [_Exploding()]


@pytest.fixture
def pm():
    from seatkit.plugins import get_plugin_manager

    pm = get_plugin_manager(autoload=False)
    pm.register_plugin(_TestPlugin(), "test-parallel")
    return pm


@pytest.mark.parametrize("processes", [True, False])
def test_an_error_of_the_baseline_surfaces_from_the_build(pm, tmp_path, processes):
    recipe = dict(RECIPE, evaluate={"enabled": True, "baseline": "broken-baseline"}, output=str(tmp_path / "out"))
    with pytest.raises(UnsupportedPoseError, match="the broken baseline cannot fit this pose") as info:
        seatkit.build(recipe, pm=pm, processes=processes)
    assert info.value.parts == ["Hips"]
    assert not (tmp_path / "out").exists()
    assert _children() == []


@pytest.mark.parametrize("processes", [True, False])
def test_a_failing_refiner_stops_the_baseline_and_leaves_no_process(pm, tmp_path, processes):
    recipe = dict(RECIPE, refiners=["explode"], output=str(tmp_path / "out"))
    with pytest.raises(SeatkitError, match="the refiner exploded"):
        seatkit.build(recipe, pm=pm, processes=processes)
    assert _children() == []


def _echo_inbox(receive, scale):
    got = receive()
    return None if got is None else got * scale


@pytest.mark.parametrize("process", [True, False])
def test_inbox_receives_what_the_parent_sends_later(process):
    work = Background(_echo_inbox, 3.0, name="inbox", process=process, inbox=True)
    work.send(np.arange(3.0))
    np.testing.assert_array_equal(work.result(), [0.0, 3.0, 6.0])
    with pytest.raises(RuntimeError, match="works once"):
        work.send(1.0)
    assert _children() == []


@pytest.mark.parametrize("process", [True, False])
def test_inbox_work_that_is_never_sent_anything_ends(process):
    assert Background(_echo_inbox, 3.0, name="inbox", process=process, inbox=True).result() is None
    work = Background(_echo_inbox, 3.0, name="inbox", process=process, inbox=True)
    work.close()
    assert _children() == []


# ----------------------------------------------------------------- the export worker

WRITE = {
    "template": "chair",
    "exporters": ["usd", "obj", "surface", "body-ply", "design", "report-html"],
    "evaluate": {"enabled": False},
}


def _same_design_files(a: Path, b: Path) -> None:
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    for name in names:
        if name in ("report.json", ".seatkit-run", "design.npz"):
            continue
        if name == "report.html":  # the same but for the time each stage took
            ha, hb = (re.sub(r"<h2>Time per stage</h2><table>.*?</table>", "", (d / name).read_text(), flags=re.S) for d in (a, b))
            assert ha == hb
            continue
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    da, db = np.load(a / "design.npz"), np.load(b / "design.npz")
    for key in da.files:
        if key != "header":
            assert da[key].tobytes() == db[key].tobytes(), key


@needs_fork
def test_the_export_worker_writes_the_same_files_as_the_main_process(tmp_path):
    from seatkit.pipeline import _Exports

    seatkit.build(dict(WRITE, output=str(tmp_path / "a")), processes=True)
    seatkit.build(dict(WRITE, output=str(tmp_path / "a")), processes=False)  # replaces its own run
    seatkit.build(dict(WRITE, output=str(tmp_path / "b")), processes=False)
    seatkit.build(dict(WRITE, output=str(tmp_path / "c")), processes=True)
    _same_design_files(tmp_path / "b", tmp_path / "c")
    # the roles are listed in recipe order whichever process wrote them
    files = list(json.loads((tmp_path / "c" / "report.json").read_text())["files"])
    assert files == list(json.loads((tmp_path / "b" / "report.json").read_text())["files"])
    # usd and report-html have prepare_ahead: they are the worker's
    from seatkit.plugins import get_plugin_manager

    reg = get_plugin_manager().registry
    exports = _Exports([reg.get("exporter", n) for n in WRITE["exporters"]], processes=True)
    exports.close()
    assert exports.ahead == [0, 5]
    assert _children() == []


class _FailingExporter:
    description = "fails"

    def __init__(self, name, prepare):
        self.name = name
        self.prepare_ahead = prepare

    def prepare(self):
        return None

    def export(self, result, directory):
        (Path(directory) / f"{self.name}.txt").write_text("half")
        raise SeatkitError(f"exporter {self.name} failed")


class _ExporterPlugin:
    @seatkit.hookimpl
    def seatkit_register_exporters(self):
        return [_FailingExporter("fail-in-worker", True), _FailingExporter("fail-here", False)]


@pytest.mark.parametrize("processes", [True, False])
@pytest.mark.parametrize("failing", ["fail-in-worker", "fail-here"])
def test_a_failing_exporter_leaves_no_output_folder_and_no_process(tmp_path, processes, failing):
    from seatkit.plugins import get_plugin_manager

    pm = get_plugin_manager(autoload=False)
    pm.register_plugin(_ExporterPlugin(), "test-exporters")
    recipe = dict(WRITE, exporters=["usd", failing, "obj"], output=str(tmp_path / "out"))
    with pytest.raises(SeatkitError, match=f"exporter {failing} failed"):
        seatkit.build(recipe, pm=pm, processes=processes)
    assert list(tmp_path.iterdir()) == []  # neither the folder nor its staging folder
    assert _children() == []


@needs_fork
def test_a_later_child_holding_a_copy_of_the_inbox_pipe_does_not_delay_the_message():
    work = Background(_echo_inbox, 2.0, name="inbox", inbox=True)
    sleeper = Background(time.sleep, 10.0, name="sleeper")  # forked with the inbox's write end open
    try:
        start = time.perf_counter()
        work.send(np.ones(3))
        np.testing.assert_array_equal(work.result(), [2.0, 2.0, 2.0])
        assert time.perf_counter() - start < 5.0
    finally:
        sleeper.close()
    assert _children() == []
