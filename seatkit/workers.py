"""The build's helper processes: standard :mod:`concurrent.futures` pools.

A build is Python driving numpy and scipy on small arrays, so two threads of
one process mostly wait for each other's GIL (the ``optimize`` refiner took
0.11 s alone and 0.41 s beside the baseline on a second thread, 2 cores).
Work that pays for its own hand-off goes to a process instead
(docs/architecture.md, "Processes of one build"):

- the baseline design (fitted beside our refiners);
- the exporters whose time goes mostly into importing a big library
  (``prepare_ahead``: usd-core, plotly, trimesh), which a worker imports
  while the design is computed and then runs beside the other exporters.

Each is a :class:`Helper`: a one-worker :class:`ProcessPoolExecutor`.

A helper's worker is a ``fork`` of the build's own process where that is
safe, so that it starts with numpy, scipy and seatkit's stages imported at
no cost (copy-on-write: nothing is imported twice): on Linux, when the
helpers are started from the main thread of a process that runs no other
thread (:func:`helper_context`; ``seatkit build`` starts its spinner only
after its helpers). The build's helpers are forked one after the other at
the start of the build; a later one is forked beside the earlier pools'
own threads (their manager and queue feeder), which only move tasks
through their own pipes and hold no lock the new worker uses. The modules
of :data:`PRELOAD` are imported first (the build needs nearly all of them
itself), so that no worker imports them again.

Elsewhere (a program that runs threads of its own, such as ``seatkit
serve``; macOS; Windows) a worker never is a ``fork`` of a process whose
threads run: the pools use ``forkserver`` where the platform has it and
``spawn`` otherwise. The fork server is started once per Python process,
from a fresh interpreter, and imports :data:`PRELOAD` first, so that each
worker forked from it starts with numpy, scipy and seatkit's stages
imported. It starts with the first pool, or earlier where a program calls
:func:`start_fork_server`.

Errors cross the boundary as they were raised (a
:class:`~seatkit.errors.SeatkitError` stays one, with the same one-line
message: it pickles by ``__reduce__``). A worker that dies (out of memory,
a signal from outside) is one clear :class:`WorkerLost` line, never a
traceback. Workers run :data:`BACKGROUND_NICE` lower than the build: on two
cores the build's own stages are the critical path. A worker ends with the
build even when the build is killed outright (``kill -9``).

A worker that is not a ``fork`` of the build is, as for every
``forkserver``/``spawn`` process, one where multiprocessing imports the caller's main
script in it again (as ``__mp_main__``): a script that builds at import
time, without ``if __name__ == "__main__":``, would run again there.
:func:`main_is_import_safe` tells whether the running program is safe that
way without being asked (the REPL, a notebook, ``python -c``);
:func:`seatkit.pipeline.build` uses helpers by default only then, and the
``seatkit`` command, whose entry point is guarded, asks for them.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import pickle
import signal
import sys
import threading
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Sequence

from seatkit.constants import BACKGROUND_NICE
from seatkit.errors import SeatkitError

__all__ = [
    "BACKGROUND_NICE",
    "PRELOAD",
    "SPARE_CORE",
    "Helper",
    "WorkerLost",
    "cpu_snapshot",
    "helper_context",
    "helpers_pay",
    "main_is_import_safe",
    "pool_context",
    "spare_cores",
    "start_fork_server",
]


#: Modules a worker must not import again: what the
#: baseline worker's jobs import (its arguments unpickled, the flat-patch
#: template, the refiners, the limit surface, the evaluation and its
#: pressure solve; then the interface pressure and a part of the report's
#: pictures: measured with ``sys.modules`` around those jobs in a process
#: that imported only these: nothing more is imported), so that no job
#: waits for an import, and nothing more. The fork server imports them
#: before it forks any worker; a build that forks its workers itself imports
#: them first (all but the first). The big exporter libraries are not
#: among them: the export worker imports those itself, beside the build, so
#: the baseline worker need not wait for them.
PRELOAD = (
    "seatkit.background",  # first: lowers the fork server's priority (and so its workers')
    "numpy",
    "scipy.sparse",
    "scipy.spatial",
    "seatkit.model",
    "seatkit.pressure",
    "seatkit.evaluate",
    "seatkit.subdivision",
    "seatkit.refine",
    "seatkit.template",
    "seatkit.stages",
    "seatkit.recipe",
    "threadpoolctl",
    "seatkit.pressure.compliant",  # the interface pressure
    "clarabel",
    "seatkit.export.report",  # the report's pictures
    "PIL.Image",
    "PIL.ImageDraw",
    "PIL.ImageFont",
)


#: The idle capacity, in cores, beside the build's own, from which helper
#: processes pay for themselves (:func:`helpers_pay`). A build with helpers
#: forked from it spends about 0.3 s more CPU than one in a single process
#: (the pickled design and result, rasters two picture parts both draw;
#: with a fork server, which imports numpy, scipy and the stages again,
#: 1.4-1.9 s) to take about 1.1 s of work off the main process's path: on
#: an idle second core that is a gain, on cores other jobs keep busy the
#: niced helpers wait and the build gains nothing
#: (docs/performance.md, "Helper processes").
SPARE_CORE = 0.5


def _cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def cpu_snapshot() -> tuple[float, float] | None:
    """(idle, total) CPU time of the whole machine so far, in clock ticks (Linux ``/proc/stat``); None elsewhere."""
    try:
        with open("/proc/stat", "rb") as fh:
            fields = fh.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != b"cpu":
        return None
    ticks = [float(x) for x in fields[1:9]]  # user nice system idle iowait irq softirq steal
    return ticks[3] + ticks[4], sum(ticks)


def spare_cores(since: tuple[float, float] | None) -> float | None:
    """Idle cores on average since the :func:`cpu_snapshot` ``since``, None when that cannot be measured.

    ``None`` too when too little time has passed to tell (fewer than 10
    ticks of the whole machine).
    """
    now = cpu_snapshot()
    if since is None or now is None or now[1] - since[1] < 10:
        return None
    cores = _cores()
    return cores * (now[0] - since[0]) / (now[1] - since[1])


def helpers_pay(since: tuple[float, float] | None) -> bool:
    """Whether the build's helper processes pay for themselves on this machine now.

    They do when a core is idle beside the build: the machine's idle time
    since ``since`` (a :func:`cpu_snapshot` taken when the program started,
    so that the window is its own start-up, when it keeps one core busy)
    is at least :data:`SPARE_CORE` of a core. On one core they never do.
    Where the idle time cannot be measured (no ``/proc/stat``) the load
    average decides: at least :data:`SPARE_CORE` below the core count
    beside this process. The environment variable ``SEATKIT_HELPERS``
    (``on``/``off``) decides instead when set (``auto`` or empty: as
    above; anything else is a :class:`~seatkit.errors.SeatkitError`).
    """
    forced = os.environ.get("SEATKIT_HELPERS", "").strip().lower()
    if forced == "on":
        return True
    if forced == "off":
        return False
    if forced not in ("", "auto"):
        msg = f"the environment variable SEATKIT_HELPERS: expected on, off or auto, got {forced[:40]!r}"
        raise SeatkitError(msg)
    cores = _cores()
    if cores < 2:
        return False
    spare = spare_cores(since)
    if spare is None:
        try:
            spare = cores - 1 - os.getloadavg()[0]
        except (AttributeError, OSError):  # no load average (Windows): as before, helpers
            return True
    return spare >= SPARE_CORE


class WorkerLost(SeatkitError):
    """A helper process of the build ended before sending its result."""


def main_is_import_safe() -> bool:
    """Whether a worker can start without running the caller's main script or module again.

    True when ``__main__`` is no file and no module (the REPL, a notebook,
    ``python -c``): multiprocessing then has nothing to import in the
    worker. A script or ``python -m`` module is imported again there, which
    is safe only under a ``__main__`` guard, which cannot be seen from here.
    """
    main = sys.modules.get("__main__")
    if main is None:
        return True
    return getattr(main, "__file__", None) is None and getattr(getattr(main, "__spec__", None), "name", None) is None


def pool_context() -> multiprocessing.context.BaseContext:
    """The multiprocessing context of seatkit's pools when they cannot fork the caller (forkserver, else spawn)."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(list(PRELOAD))
        return ctx
    return multiprocessing.get_context("spawn")


def _can_fork() -> bool:
    """Whether a worker may be a ``fork`` of this process now: Linux, the main thread, no other thread running."""
    if sys.platform != "linux" or "fork" not in multiprocessing.get_all_start_methods():
        return False
    return threading.current_thread() is threading.main_thread() and threading.active_count() == 1


def helper_context() -> multiprocessing.context.BaseContext:
    """The context for the helpers a caller is about to start: ``fork`` when :func:`_can_fork`, else :func:`pool_context`.

    Asked once, before the first helper of a build starts (the helpers'
    own pool threads then run beside the later forks; see the module's
    documentation).
    """
    return multiprocessing.get_context("fork") if _can_fork() else pool_context()


def start_fork_server() -> None:
    """Start the fork server now, so that it imports :data:`PRELOAD` while the caller starts up.

    The first :class:`Helper` would start it anyway, at the beginning of the
    build; a program that knows it will build (``seatkit build``) calls this
    before its own start-up work (the plugins, the recipe), so that the fork
    server's imports run beside the program's own instead of beside the
    build's first stages. It does nothing where the helpers would be forks
    of this process (:func:`helper_context`), and without a fork server
    (spawn platforms: every worker is a fresh interpreter there anyway).
    """
    if not _can_fork() and "forkserver" in multiprocessing.get_all_start_methods():
        from multiprocessing import forkserver

        pool_context()  # sets PRELOAD
        forkserver.ensure_running()


def _end_with_the_build() -> None:
    """End this worker as soon as the build's process ends, however it ends.

    ``multiprocessing.parent_process()`` is the process that asked for this
    worker (the build, not the fork server that forked it); its sentinel
    becomes ready when that process is gone. A worker of a build killed with
    ``kill -9`` would otherwise wait for its next task forever (it holds
    both ends of its task queue) and keep the fork server alive with it.
    """
    parent = multiprocessing.parent_process()
    if parent is None:  # pragma: no cover - not started by multiprocessing
        return

    def watch() -> None:
        parent.join()
        os._exit(1)

    threading.Thread(target=watch, name="seatkit-watch-build", daemon=True).start()


def _start_worker(prepare: Sequence[Any], lower: bool = False) -> None:
    """A worker's first step: run below the build, end with it, then get its exporters ready.

    ``lower``: a ``fork`` of the build, which runs at the build's priority
    (a worker of the fork server runs at the fork server's, lowered by
    :mod:`seatkit.background`).
    """
    if lower:
        _lower_priority()
    _end_with_the_build()
    if "forkserver" not in multiprocessing.get_all_start_methods():  # spawned: not forked from the niced fork server
        import seatkit.background  # noqa: F401
    for exporter in prepare:
        exporter.prepare()


def _lower_priority() -> None:
    try:
        os.nice(BACKGROUND_NICE)
    except (AttributeError, OSError):  # no nice() (Windows), or not allowed
        pass


def _share_imports() -> None:
    """Import :data:`PRELOAD` here (but :mod:`seatkit.background`, which would lower this process), so that forked workers share them."""
    for name in PRELOAD:
        if name != "seatkit.background":
            importlib.import_module(name)


class Helper:
    """One helper process of a build: a one-worker :class:`ProcessPoolExecutor`, started now.

    The worker starts at once, not at the first :meth:`submit`, so that it
    gets ready (imports, ``prepare()`` of ``exporters``) while the build
    computes what it will be given. A ``fork`` of this process starts at
    once; a worker of the fork server waits until the fork server has
    imported :data:`PRELOAD` and forked it, so it is asked for on a thread
    (starting the fork server is a fork+exec, safe beside threads) and the
    build goes on meanwhile.

    Parameters
    ----------
    what : str
        Names the work in the :class:`WorkerLost` message.
    exporters : sequence of Exporter
        Prepared by the worker as it starts (they are pickled to it).
    context : multiprocessing context, optional
        Default :func:`helper_context`; a caller that starts several
        helpers asks for it once, before the first.
    """

    def __init__(self, what: str, exporters: Sequence[Any] = (), context: multiprocessing.context.BaseContext | None = None):
        self.what = what
        context = context if context is not None else helper_context()
        forked = context.get_start_method() == "fork"
        if forked:
            _share_imports()
        self._pool = ProcessPoolExecutor(max_workers=1, mp_context=context, initializer=_start_worker, initargs=(tuple(exporters), forked))
        self._jobs: list[Future] = []
        self._ending: threading.Thread | None = None  # the pool's shutdown after release()
        self._started: list[Future] = []  # the first task: the worker's process id
        if forked:  # a fork takes milliseconds: now, before this process starts any other thread
            self._started.append(self._pool.submit(os.getpid))
            self._start = None
            return
        self._start = threading.Thread(target=lambda: self._started.append(self._pool.submit(os.getpid)), name=f"seatkit-{what}-start", daemon=True)
        self._start.start()

    def submit(self, fn: Callable, *args: Any) -> Future:
        """Run ``fn(*args)`` in the worker (arguments and value are pickled)."""
        job = self._pool.submit(_portable_call, fn, *args)
        self._jobs.append(job)
        return job

    def idle(self) -> bool:
        """Whether every task submitted so far is done (a new one would start at once)."""
        return all(job.done() for job in self._jobs)

    def result(self, future: Future) -> Any:
        """A task's value, its error re-raised, or :class:`WorkerLost` if the worker died."""
        try:
            return future.result()
        except BrokenProcessPool:
            # one clear line, not a traceback: the cause is outside seatkit
            msg = f"the {self.what} process ended before sending its result (out of memory, or stopped from outside seatkit)"
            raise WorkerLost(msg) from None

    def pid(self) -> int:
        """The worker's process id."""
        if self._start is not None:
            self._start.join()
        return self.result(self._started[0])

    def release(self) -> None:
        """No more tasks: the worker ends once those submitted are done, beside what the caller does next.

        The pool's shutdown (the worker told to end, its exit waited for)
        runs on a thread; :meth:`close` waits for it. A build releases its
        helpers once it has their files, before it writes ``report.json``.
        """
        if self._ending is None:
            self._ending = threading.Thread(target=self._pool.shutdown, name=f"seatkit-{self.what}-end", daemon=True)
            self._ending.start()

    def close(self, *, stop: bool = False) -> None:
        """End the worker (idempotent); with ``stop``, work it still does is stopped, not waited for.

        A build that failed stops its helpers (``SIGTERM``): their results
        are no longer wanted.
        """
        if self._start is not None:
            self._start.join()
        if stop and any(not job.done() for job in self._jobs):
            try:
                os.kill(self.pid(), signal.SIGTERM)
            except (ProcessLookupError, WorkerLost):
                pass
        if self._ending is not None:
            self._ending.join()
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> "Helper":
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close(stop=exc_type is not None)


def _portable_error(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else the nearest thing that does (same message)."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001 - any failure to round-trip
        if isinstance(exc, SeatkitError):
            return SeatkitError(str(exc))
        return RuntimeError(f"{type(exc).__name__}: {exc}")


def _portable_call(fn: Callable, *args: Any) -> Any:
    """``fn(*args)`` in a worker, its error made to survive the way back (:func:`_portable_error`)."""
    try:
        return fn(*args)
    except Exception as exc:  # noqa: BLE001 - re-raised in the build, as it was or as near as pickling allows
        portable = _portable_error(exc)
        if portable is exc:
            raise
        raise portable from None
