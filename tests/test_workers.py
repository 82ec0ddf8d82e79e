"""The build's helper processes (concurrent.futures pools, seatkit.workers): values, errors, clean-up, and the build's results with and without them."""

from __future__ import annotations

import json
import os
import pickle
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import seatkit
from seatkit.errors import MissingExtraError, SeatkitError, UnsupportedPoseError
from seatkit.workers import Helper, WorkerLost


def _processes() -> dict[int, tuple[int, str, str]]:
    """pid -> (parent pid, state, command line) of every process (Linux /proc)."""
    out = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
            cmd = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        fields = text[text.rindex(")") + 2 :].split()
        out[int(stat.parent.name)] = (int(fields[1]), fields[0], cmd)
    return out


def _descendants() -> set[tuple[int, str]]:
    """(pid, state) of this process's descendants, zombies included, but for multiprocessing's servers.

    The fork server and the resource tracker live as long as this process,
    by design (the workers are forked from the fork server,
    :mod:`seatkit.workers`); their children are counted.
    """
    procs, out, todo = _processes(), set(), [os.getpid()]
    while todo:
        parent = todo.pop()
        for pid, (ppid, state, cmd) in procs.items():
            if ppid == parent:
                todo.append(pid)
                server = parent == os.getpid() and any(f"multiprocessing.{n} import main" in cmd for n in ("forkserver", "resource_tracker"))
                if not server:  # (the workers forked by the fork server have its command line too)
                    out.add((pid, state))
    return out


_BEFORE: set = set()


@pytest.fixture(autouse=True)
def _note_children():
    """Processes that other tests of the session left (a Dask cluster...) are not ours."""
    _BEFORE.clear()
    _BEFORE.update(pid for pid, _ in _descendants())


def _children(wait: float = 5.0) -> list[tuple[int, str]]:
    """Processes started (and not reaped) since the test began, after up to ``wait`` s for them to be reaped."""
    deadline = time.monotonic() + wait
    while True:
        left = sorted(c for c in _descendants() if c[0] not in _BEFORE)
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.05)


needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="counts processes in /proc (Linux)")


def _square_pid(x):
    return x * x, os.getpid()


def _raise(exc):
    raise exc


class _Unpicklable(SeatkitError):
    def __init__(self, message):
        super().__init__(message)
        self.hook = lambda: None  # a lambda cannot be pickled


def _raise_unpicklable(message):
    raise _Unpicklable(message)


@needs_proc
def test_value_comes_back_from_another_process_and_the_worker_ends():
    with Helper("square") as work:
        job = work.submit(_square_pid, np.arange(4.0))
        value, pid = work.result(job)
        assert work.result(job)[1] == pid  # asking again gives the same answer
        assert work.pid() == pid
    np.testing.assert_array_equal(value, np.arange(4.0) ** 2)
    assert pid != os.getpid()
    assert _children() == []


def test_a_seatkit_error_keeps_its_type_message_and_attributes():
    err = UnsupportedPoseError("the knees cannot be supported", parts=["LeftShin"], diagnostics={"faces": 3})
    with Helper("baseline") as work, pytest.raises(UnsupportedPoseError, match="the knees cannot be supported") as info:
        work.result(work.submit(_raise, err))
    assert str(info.value) == "the knees cannot be supported"
    assert info.value.parts == ["LeftShin"]
    assert info.value.diagnostics == {"faces": 3}


def test_an_error_that_cannot_be_pickled_still_arrives_as_a_seatkit_error():
    with Helper("x") as work, pytest.raises(SeatkitError, match="no picklable error"):
        work.result(work.submit(_raise_unpicklable, "no picklable error"))


def test_missing_extra_error_survives_pickling():
    err = pickle.loads(pickle.dumps(MissingExtraError("dask[distributed]", "batch")))
    assert (err.package, err.extra) == ("dask[distributed]", "batch")
    assert "pip install 'seatkit[batch]'" in str(err)


@needs_proc
def test_a_worker_that_dies_is_reported_not_waited_for_forever():
    # one clear error (a SeatkitError: the CLI prints one line, no traceback)
    with Helper("crash") as work, pytest.raises(WorkerLost, match="^the crash process ended before sending its result"):
        work.result(work.submit(os._exit, 3))
    assert _children() == []


@needs_proc
def test_close_with_stop_ends_a_worker_that_is_still_running():
    work = Helper("sleeper")
    work.submit(time.sleep, 30.0)
    pid = work.pid()
    assert [p for p, _ in _children(wait=0)] == [pid]  # (running or sleeping: the machine may be busy)
    start = time.perf_counter()
    work.close(stop=True)
    assert time.perf_counter() - start < 5.0
    assert _children() == []


class _Prepared:
    """An exporter whose prepare() leaves its process id in a file."""

    name = "prepared"
    description = "notes where prepare() ran"
    prepare_ahead = True

    def __init__(self, path):
        self.path = str(path)

    def prepare(self):
        Path(self.path).write_text(str(os.getpid()))

    def export(self, result, directory):
        return {}


def test_the_export_worker_prepares_its_exporters_as_it_starts(tmp_path):
    note = tmp_path / "prepared.txt"
    with Helper("export", [_Prepared(note)]) as work:
        pid = work.pid()
        assert note.read_text() == str(pid) != str(os.getpid())  # before any task was given


# ------------------------------------------------------------------ inside a build

RECIPE = {
    "template": "chair",
    "refiners": [],
    "exporters": [],
    "evaluate": {"enabled": True, "baseline": "flat-patch"},
}


@needs_proc
def _untimed(value):
    """``value`` without the wall times it holds (keys ending in ``_seconds``): they differ from run to run."""
    if isinstance(value, dict):
        return {k: _untimed(v) for k, v in value.items() if not str(k).endswith("_seconds")}
    if isinstance(value, list):
        return [_untimed(v) for v in value]
    return value


def test_build_gives_the_same_results_with_the_baseline_in_a_process_or_in_sequence():
    a = seatkit.build(dict(RECIPE), write=False, processes=True)
    b = seatkit.build(dict(RECIPE), write=False, processes=False)
    assert _untimed(a.metrics) == _untimed(b.metrics)
    assert a.metrics["baseline"][0]["supported"] is True
    for key in ("control_mesh", "surface"):
        np.testing.assert_array_equal(getattr(a.baseline, key).vertices, getattr(b.baseline, key).vertices)
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


@needs_proc
def test_the_export_worker_writes_the_same_files_as_the_main_process(tmp_path):
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
    assert [i for i, n in enumerate(WRITE["exporters"]) if reg.get("exporter", n).prepare_ahead] == [0, 5]
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


# ------------------------------------------------- the design's files, beside the evaluation

#: The template's cage (quick), evaluated without a baseline or the interface pressure: the
#: design's files are written as soon as it is made, beside the evaluation.
FULL = {"template": "chair", "refiners": [], "evaluate": {"enabled": True, "baseline": None, "interface_pressure": False}}


@needs_proc
@pytest.mark.parametrize(
    "recipe",
    [
        {"template": "chair"},  # the default build: refined, evaluated against the baseline (framed in the pictures too)
        FULL,
    ],
    ids=["default", "no-baseline"],
)
def test_a_build_with_helpers_writes_every_default_file_as_one_process_does(tmp_path, recipe, monkeypatch):
    """The design's files written beside the evaluation, the pictures in three processes: the same bytes as in one process."""
    import seatkit.pipeline as pipeline

    hand_over = pipeline._hand_over

    def on_a_quiet_machine(designed, result, baseline, job):  # the baseline fitted before our surface, as there
        if job is not None:
            job.result()
        hand_over(designed, result, baseline, job)

    monkeypatch.setattr(pipeline, "_hand_over", on_a_quiet_machine)
    seatkit.build(dict(recipe, output=str(tmp_path / "one")), processes=False)
    seatkit.build(dict(recipe, output=str(tmp_path / "three")), processes=True)
    _same_design_files(tmp_path / "one", tmp_path / "three")
    files = [json.loads((tmp_path / d / "report.json").read_text())["files"] for d in ("one", "three")]
    assert list(files[0]) == list(files[1])  # in recipe order, whichever process wrote them
    assert {"usd", "cage_obj", "surface_obj", "design", "report_cage_png", "report_surface_png", "report_html"} <= set(files[0])
    assert [p.name for p in tmp_path.iterdir()] and not [p for p in tmp_path.iterdir() if ".staging-" in p.name]
    assert _children() == []


class _DesignOnly:
    """A third-party exporter that needs only the design: the cage's size and the evaluation it saw."""

    description = "counts"
    prepare_ahead = False
    design_only = True

    def __init__(self, name, fail=None):
        self.name = name
        self.fail = fail
        self.owner = os.getpid()  # the build's process (a helper gets a copy of this exporter, pid included)

    def prepare(self):
        return None

    def export(self, result, directory):
        if self.fail == "error":
            raise SeatkitError(f"exporter {self.name} failed")
        if self.fail == "die" and os.getpid() != self.owner:
            os._exit(3)  # the worker dies (out of memory, a signal from outside)
        path = Path(directory) / f"{self.name}.txt"
        path.write_text(f"{len(result.control_mesh.vertices)} {len(result.surface.vertices)} {len(result.bodies)}\n")
        return {self.name: path}


class _DesignParts:
    """A third-party exporter in two parts, the first of which needs only the design."""

    name = "two-parts"
    description = "two parts"
    prepare_ahead = False
    runs_apart = True
    parts = 2
    design_parts = (0,)

    def prepare(self):
        return None

    def export(self, result, directory):
        return {**self.export_part(result, directory, 0), **self.export_part(result, directory, 1)}

    def export_part(self, result, directory, part):
        path = Path(directory) / f"part{part}.txt"
        # part 1 shows the evaluation, which the design-only part 0 must not need
        path.write_text(f"{len(result.control_mesh.vertices)}\n" if part == 0 else f"{result.metrics['ours'][0]['supported']}\n")
        return {f"part{part}": path}


class _DesignPlugin:
    @seatkit.hookimpl
    def seatkit_register_exporters(self):
        return [_DesignOnly("counts"), _DesignOnly("fails", "error"), _DesignOnly("dies", "die"), _DesignParts()]


@pytest.fixture
def design_pm():
    from seatkit.plugins import get_plugin_manager

    pm = get_plugin_manager(autoload=False)
    pm.register_plugin(_DesignPlugin(), "test-design-exporters")
    return pm


@needs_proc
def test_a_plugin_exporter_that_needs_only_the_design_writes_the_same_files_with_helpers(tmp_path, design_pm):
    exporters = ["usd", "counts", "two-parts", "report-html"]
    for processes, out in ((True, "a"), (False, "b")):
        seatkit.build(dict(FULL, exporters=exporters, output=str(tmp_path / out)), pm=design_pm, processes=processes)
    for name in ("counts.txt", "part0.txt", "part1.txt", "cage.usda"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    assert (tmp_path / "a" / "part1.txt").read_text() == "True\n"
    files = json.loads((tmp_path / "a" / "report.json").read_text())["files"]
    assert list(files) == list(json.loads((tmp_path / "b" / "report.json").read_text())["files"])
    assert list(files)[:4] == ["usd", "counts", "part0", "part1"]
    assert _children() == []


@needs_proc
@pytest.mark.parametrize("processes", [True, False])
def test_a_failing_design_exporter_is_one_error_and_leaves_no_output_and_no_process(tmp_path, design_pm, processes):
    recipe = dict(FULL, exporters=["usd", "fails", "obj"], output=str(tmp_path / "out"))
    with pytest.raises(SeatkitError, match="^exporter fails failed$"):
        seatkit.build(recipe, pm=design_pm, processes=processes)
    assert list(tmp_path.iterdir()) == []  # neither the folder nor its staging folder
    assert _children() == []


@needs_proc
def test_a_helper_that_dies_writing_the_design_is_one_clear_error(tmp_path, design_pm):
    recipe = dict(FULL, exporters=["usd", "dies", "obj"], output=str(tmp_path / "out"))
    with pytest.raises(WorkerLost, match="^the export process ended before sending its result"):
        seatkit.build(recipe, pm=design_pm, processes=True)
    assert list(tmp_path.iterdir()) == []
    assert _children() == []


@needs_proc
def test_an_evaluation_that_fails_while_the_design_is_written_leaves_no_output_and_no_process(tmp_path, monkeypatch):
    import seatkit.pipeline as pipeline

    def fails(*args, **kwargs):
        raise SeatkitError("the evaluation failed")

    monkeypatch.setattr(pipeline, "evaluate_result", fails)
    with pytest.raises(SeatkitError, match="^the evaluation failed$"):
        seatkit.build(dict(FULL, output=str(tmp_path / "out")), processes=True)
    assert list(tmp_path.iterdir()) == []  # the staging folder the design's files went into is gone
    assert _children() == []


def test_a_script_without_a_main_guard_builds_once_by_default(tmp_path):
    # multiprocessing imports the main script again in a forkserver/spawn
    # worker: by default a script's build stays in its process, so a script
    # that builds at import time runs once, as it reads
    import subprocess
    import sys

    script = tmp_path / "unguarded.py"
    script.write_text(
        "import seatkit\n"
        "from seatkit.workers import main_is_import_safe\n"
        "print('building', main_is_import_safe(), flush=True)\n"
        f"r = seatkit.build({dict(RECIPE)!r}, write=False)\n"
        "print('baseline', r.metrics['baseline'][0]['supported'], flush=True)\n"
    )
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["building False", "baseline True"]
    # python -c has no main to import again: helpers by default there
    code = "from seatkit.workers import main_is_import_safe; print(main_is_import_safe())"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip() == "True"


@pytest.mark.skipif(not hasattr(os, "nice"), reason="POSIX niceness")
def test_workers_run_below_the_build_and_the_build_keeps_its_priority():
    from seatkit.workers import BACKGROUND_NICE

    mine = os.nice(0)
    with Helper("nice") as work:
        theirs = work.result(work.submit(os.nice, 0))
    assert os.nice(0) == mine  # importing seatkit.workers does not lower the build
    assert theirs == min(mine + BACKGROUND_NICE, 19)


_PRELOAD_CHECK = """
import importlib, pickle, sys
from seatkit.workers import PRELOAD
for name in PRELOAD:
    importlib.import_module(name)
before = set(sys.modules)
recipe, bodies, pressures, components, segments = pickle.loads(sys.stdin.buffer.read())
from seatkit.stages import fit_baseline_with
base = fit_baseline_with(recipe, bodies, pressures, components, segments)
from seatkit.evaluate import evaluate_interface
evaluate_interface(bodies, base.surface)  # the worker's next job, when idle
print(" ".join(sorted(set(sys.modules) - before)))
"""


def test_the_fork_server_preloads_every_module_the_baseline_job_imports():
    """PRELOAD is what a baseline job and the interface pressure import (their arguments unpickled, the fit, the evaluation), so no worker imports it again."""
    import subprocess
    import sys

    from seatkit.evaluate import design_segments
    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import apply_overrides, check_recipe, load_recipe
    from seatkit.stages import baseline_components, make_bodies, solve_importance

    registry = get_plugin_manager().registry
    recipe = check_recipe(apply_overrides(load_recipe(None)[0], template="chair", poses=["lounger"]), registry)
    bodies = make_bodies(recipe, registry)
    pressures = solve_importance(recipe, bodies, registry)
    cage = registry.get("template", "chair").fit(bodies, pressures, params=recipe["template_params"], seed=recipe["seed"])
    job = pickle.dumps((recipe, bodies, pressures, baseline_components(recipe, registry), design_segments(cage)))
    done = subprocess.run([sys.executable, "-c", _PRELOAD_CHECK], input=job, capture_output=True, check=True)
    assert done.stdout.decode().split() == []


def _machine(monkeypatch, *, cores: int, idle_ticks: float, total_ticks: float):
    """A machine of ``cores`` whose CPU ticks grow by ``total_ticks`` (``idle_ticks`` of them idle) after the first snapshot."""
    import seatkit.workers as workers

    ticks = iter([(1000.0, 5000.0), (1000.0 + idle_ticks, 5000.0 + total_ticks)])
    monkeypatch.setattr(workers, "cpu_snapshot", lambda: next(ticks))
    monkeypatch.setattr(workers.os, "sched_getaffinity", lambda pid: set(range(cores)), raising=False)
    monkeypatch.delenv("SEATKIT_HELPERS", raising=False)
    return workers


def test_helpers_are_used_with_an_idle_core_and_not_on_a_busy_machine(monkeypatch):
    # two cores, the build busy on one: one core idle over its start-up -> helpers
    workers = _machine(monkeypatch, cores=2, idle_ticks=50, total_ticks=100)
    assert workers.spare_cores(workers.cpu_snapshot()) == pytest.approx(1.0)
    workers = _machine(monkeypatch, cores=2, idle_ticks=50, total_ticks=100)
    assert workers.helpers_pay(workers.cpu_snapshot()) is True
    # other jobs keep the second core busy: nothing idle -> one process
    workers = _machine(monkeypatch, cores=2, idle_ticks=5, total_ticks=100)
    assert workers.helpers_pay(workers.cpu_snapshot()) is False
    # one core: never
    workers = _machine(monkeypatch, cores=1, idle_ticks=100, total_ticks=100)
    assert workers.helpers_pay(workers.cpu_snapshot()) is False


def test_seatkit_helpers_decides_when_set(monkeypatch):
    workers = _machine(monkeypatch, cores=2, idle_ticks=0, total_ticks=100)
    monkeypatch.setenv("SEATKIT_HELPERS", "on")
    assert workers.helpers_pay(workers.cpu_snapshot()) is True
    workers = _machine(monkeypatch, cores=2, idle_ticks=100, total_ticks=100)
    monkeypatch.setenv("SEATKIT_HELPERS", "off")
    assert workers.helpers_pay(workers.cpu_snapshot()) is False
    monkeypatch.setenv("SEATKIT_HELPERS", "sometimes")
    with pytest.raises(SeatkitError, match="SEATKIT_HELPERS: expected on, off or auto, got 'sometimes'"):
        workers.helpers_pay(None)


def test_without_a_measurement_the_load_average_decides(monkeypatch):
    import seatkit.workers as workers

    monkeypatch.setattr(workers, "cpu_snapshot", lambda: None)
    monkeypatch.setattr(workers.os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    monkeypatch.delenv("SEATKIT_HELPERS", raising=False)
    monkeypatch.setattr(workers.os, "getloadavg", lambda: (0.2, 0.2, 0.2))
    assert workers.helpers_pay(None) is True
    monkeypatch.setattr(workers.os, "getloadavg", lambda: (1.8, 1.5, 1.0))
    assert workers.helpers_pay(None) is False


_DECISION_CHECK = """
import sys
import seatkit.workers as workers
seen = []
def spare(since, _spare=workers.spare_cores):
    seen.append(_spare(since))
    raise SystemExit(0)  # the decision is all this check needs
workers.spare_cores = spare
sys.argv = ["seatkit", "build", "-q", "--template", "chair", "--out", sys.argv[1]]
from seatkit import cli
cli.run()
print(seen)
"""


@needs_proc
def test_seatkit_build_decides_on_helpers_from_its_own_start_up(tmp_path, monkeypatch):
    # the idle time is measured over the program's start-up up to the
    # decision; a window too short to measure (fewer than 10 clock ticks)
    # would leave it to the load average, which the build itself raises
    monkeypatch.delenv("SEATKIT_HELPERS", raising=False)
    done = subprocess.run([sys.executable, "-c", _DECISION_CHECK, str(tmp_path / "out")], capture_output=True, text=True, check=True)
    (spare,) = eval(done.stdout.strip())
    assert spare is not None and 0.0 <= spare <= os.cpu_count() + 1e-9
    assert not (tmp_path / "out").exists()


@needs_proc
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="helpers are forks of the build on Linux only")
def test_a_worker_is_a_fork_of_the_build_only_while_no_other_thread_runs():
    # a fork copies the build's imports (nothing imported twice); beside a
    # running thread (a spinner, a server's) it could copy a lock that
    # thread holds, so the worker comes from the fork server instead
    import threading

    from seatkit.workers import helper_context

    def parent_of(pid):
        return _processes()[pid][0]

    # alone: in a fresh interpreter (this test process may run other tests' threads)
    alone = (
        "import os\n"
        "from seatkit.workers import Helper\n"
        "with Helper('alone') as work:\n"
        "    print(work.result(work.submit(os.getppid)) == os.getpid(), work.result(work.submit(pow, 3, 2)))\n"
    )
    done = subprocess.run([sys.executable, "-c", alone], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "9"]
    stop = threading.Event()
    other = threading.Thread(target=stop.wait, daemon=True)
    other.start()
    try:
        assert helper_context().get_start_method() != "fork"
        with Helper("beside a thread") as work:
            pid = work.pid()
            assert parent_of(pid) != os.getpid()
            assert work.result(work.submit(_square_pid, 3.0))[0] == 9.0
    finally:
        stop.set()
        other.join()
    assert _children() == []
