"""The timeline of one default build: when each stage, exporter and helper job starts and ends, with the CPU spent by then.

    python benchmarks/build_timeline.py [--phases] [-- extra seatkit build flags]
    /path/to/previous/.venv/bin/python benchmarks/build_timeline.py --phases   # the previous code, the same way

Runs ``seatkit build -q --template chair`` in this process (the command's
own code path, ``seatkit.cli.run``; helper processes as the command decides,
``SEATKIT_HELPERS=on``/``off`` to force them) with the build's stages,
exporter calls, helper jobs and the end of its helpers logged. Each line:
wall seconds since this script started, the CPU seconds (user + system) of
the process that logged it, and the event; lines of a helper process carry
its process id and its own CPU (counted from its fork). The main process's
lines show what the build's critical path does and when it waits for a
helper (a ``done`` after its own work has ended). ``--phases`` prints only
the main process's CPU at the start of the first stage, of the export stage,
at its end and at the end of the command, the export stage's wall time and
that from the end of the surface stage to the end of the export stage, and
the CPU the helpers spent in exporter calls: in the export stage, before it
(the design's files, written beside the evaluation) and in
``export_early`` (one line, for comparing two versions of the code run the
same way).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

T0 = time.perf_counter()
MAIN = os.getpid()
LOG: list[tuple[float, float, str]] = []


def _cpu() -> float:
    t = os.times()
    return t.user + t.system


#: A file the helper processes append their lines to (set by main(); the helpers are forks and inherit it).
HELPER_LOG: Path | None = None


def log(what: str) -> None:
    if os.getpid() == MAIN:
        LOG.append((time.perf_counter() - T0, _cpu(), what))
    else:  # a helper: printed at once (its log dies with it)
        print(f"  [{os.getpid()}] {time.perf_counter() - T0:7.3f} s  cpu {_cpu():6.3f} s  {what}", file=sys.stderr, flush=True)
        if HELPER_LOG is not None:
            with open(HELPER_LOG, "a") as fh:
                fh.write(f"{os.getpid()}\t{_cpu()}\t{what}\t{time.perf_counter() - T0}\n")


def _helpers_exporting_cpu(export_start: float) -> tuple[float, float, float]:
    """The helpers' CPU in exporter calls: ``export``/``export_part`` in the export stage, before it (the design's files, beside the evaluation), and ``export_early``."""
    stage = design = early = 0.0
    started: dict = {}
    if HELPER_LOG is None or not HELPER_LOG.exists():
        return stage, design, early
    for line in HELPER_LOG.read_text().splitlines():
        pid, cpu, what, wall = line.split("\t")
        kind, _, name = what.partition(" ")
        method = name.rpartition(".")[2]
        if method not in ("export", "export_part", "export_early"):
            continue
        if kind == "start":
            started[pid, name] = (float(cpu), float(wall))
        elif kind == "end" and (pid, name) in started:
            cpu0, wall0 = started.pop((pid, name))
            spent = float(cpu) - cpu0
            if method == "export_early":
                early += spent
            elif wall0 < export_start:
                design += spent
            else:
                stage += spent
    return stage, design, early


def _instrument() -> None:
    """Log the stages, the components' calls, the helper jobs and the helpers' end (helpers inherit it: they are forks)."""
    import seatkit.cli  # noqa: F401  (imported before the clock of the first event)
    import seatkit.plugins as plugins
    import seatkit.stages as stages
    import seatkit.workers as workers

    log("seatkit.cli imported")
    call = plugins.Guarded._call

    def guarded_call(self, method, *args, **kwargs):
        name = f"{self._component.name}.{method.__name__}"
        if method.__name__ not in ("run",):  # template steps: too many lines
            log(f"start {name}")
        try:
            return call(self, method, *args, **kwargs)
        finally:
            if method.__name__ not in ("run",):
                log(f"end {name}")

    plugins.Guarded._call = guarded_call
    stage = stages.StageTimer.stage

    @contextlib.contextmanager
    def timed_stage(self, name):
        log(f"stage> {name}")
        with stage(self, name):
            yield
        log(f"stage< {name}")

    stages.StageTimer.stage = timed_stage
    submit = workers.Helper.submit

    def logged_submit(self, fn, *args):
        label = f"{self.what}:{getattr(fn, '__name__', None) or getattr(getattr(fn, 'func', None), '__name__', repr(fn))}"
        log(f"submit {label}")
        job = submit(self, fn, *args)
        job.add_done_callback(lambda _: log(f"done {label}"))
        return job

    workers.Helper.submit = logged_submit
    close = workers.Helper.close

    def logged_close(self, **kwargs):
        log(f"close> {self.what}")
        close(self, **kwargs)
        log(f"close< {self.what}")

    workers.Helper.close = logged_close


def _at(what: str, wall: bool = False) -> float:
    return next((t if wall else cpu for t, cpu, w in LOG if w == what), float("nan"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--phases", action="store_true", help="one line: the main process's CPU at the start of the first stage, of the export stage, at its end and at the end")
    ap.add_argument("extra", nargs="*", help="more flags for seatkit build")
    args = ap.parse_args()
    _instrument()
    import seatkit.cli as cli

    global HELPER_LOG
    with tempfile.TemporaryDirectory() as tmp:
        HELPER_LOG = Path(tmp) / "helpers.log"
        sys.argv = ["seatkit", "build", "-q", "--template", "chair", "--out", str(Path(tmp) / "out"), *args.extra]
        if hasattr(cli, "run"):
            code = cli.run()
        else:  # code from before seatkit.cli.run
            try:
                cli.main()
                code = 0
            except SystemExit as e:
                code = e.code
        log("command done")
        stage, design, early = _helpers_exporting_cpu(_at("stage> export", wall=True))
    if code not in (0, None):
        sys.exit(f"the build failed (exit status {code})")
    if args.phases:
        first = _at("stage> bodies")
        export, exported, done = _at("stage> export"), _at("stage< export"), _at("command done")
        export_wall = _at("stage< export", wall=True) - _at("stage> export", wall=True)
        surface_to_end = _at("stage< export", wall=True) - _at("stage< surface", wall=True)
        print(f"main process CPU: start-up {first:.3f} s, design {export - first:.3f} s, export {exported - export:.3f} s, after it {done - exported:.3f} s, in all {done:.3f} s; "
              f"wall: the export stage {export_wall:.3f} s, from the surface to its end {surface_to_end:.3f} s; "
              f"the helpers' CPU in exporters {stage:.3f} s, before the export stage {design:.3f} s (the design's files) and {early:.3f} s (export_early)")
        return
    print(f"{'wall':>8} {'cpu':>8}  main process (helpers' lines on stderr, as they happen)")
    for wall, cpu, what in LOG:
        print(f"{wall:7.3f} s {cpu:6.3f} s  {what}")


if __name__ == "__main__":
    main()
