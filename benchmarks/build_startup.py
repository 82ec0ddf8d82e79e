"""What the default build's own process does before its first stage, phase by phase, two versions of the code alternating.

    python benchmarks/build_startup.py [--runs 8] [--old /path/to/previous/.venv/bin/python] [--template chair] [-- extra seatkit build flags]

Each run is a fresh process that starts ``seatkit build -q --template
chair`` as the ``seatkit`` command does (``from seatkit.cli import main``,
bytecode cache on) and stops it when its first stage (``bodies``) starts.
The process reads its own CPU time (user + system, from its start, the
interpreter's included) at the end of each phase:

- ``import seatkit.cli``: what the command's entry point imports;
- *the command's imports*: the options read and what ``seatkit build``
  imports before it starts (the pipeline, the stages: numpy and scipy),
  up to its call of :func:`seatkit.workers.helpers_pay`;
- *plugin manager*: the entry points listed, the plugins imported;
- *registry*: every component registered (the plugins' registration hooks:
  the template files read, the modules they import) and the templates
  bound to their steps;
- *recipe*: the recipe made from the options and checked;
- *to the first stage*: the build's set-up (the output folder claimed,
  the exporters looked up, the helper processes started: forked after
  :func:`seatkit.workers._share_imports`).

Also printed: the garbage collector's own CPU time and collections in all
that (read with :data:`gc.callbacks`) and the modules imported. With
``--old`` (the Python of an install of the previous code) the two versions
run in turn, swapped every round, and the medians are printed side by side
with the median of the per-round ratios of the total. ``SEATKIT_HELPERS``
is ``on`` unless set: both versions fork their helpers, whatever the load.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

#: Run in the measured process: checkpoints by wrapping functions as their modules are imported, then the command.
_DRIVER = r"""
import gc, importlib.abc, importlib.util, json, os, sys, time
T = []
GC = [0.0, 0, 0.0]
def _gc(phase, info):
    if phase == "start":
        GC[2] = time.process_time()
    else:
        GC[0] += time.process_time() - GC[2]
        GC[1] += 1
gc.callbacks.append(_gc)
def mark(what):
    T.append((what, time.process_time(), GC[0], GC[1], len(sys.modules)))
def wrap_call(module, owner, name, what, before=False):
    target = getattr(module, owner) if owner else module
    fn = getattr(target, name)
    def wrapped(*a, **k):
        if before:
            mark(what)
        out = fn(*a, **k)
        if not before:
            mark(what)
        return out
    setattr(target, name, wrapped)
def first_stage(stages):
    def stage(self, name):
        mark("first stage")
        os.write(1, json.dumps(T).encode())
        os._exit(0)
    stages.StageTimer.stage = stage
PATCHES = {
    "seatkit.workers": lambda m: wrap_call(m, None, "helpers_pay", "the command's imports", before=True),
    "seatkit.plugins": lambda m: wrap_call(m, None, "get_plugin_manager", "plugin manager"),
    "seatkit.recipe": lambda m: wrap_call(m, None, "check_recipe", "recipe"),
    "seatkit.stages": first_stage,
}
class After(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name not in PATCHES:
            return None
        sys.meta_path.remove(self)
        try:
            spec = importlib.util.find_spec(name)
        finally:
            sys.meta_path.insert(0, self)
        run = spec.loader.exec_module
        def exec_module(module):
            run(module)
            PATCHES.pop(name)(module)
        spec.loader.exec_module = exec_module
        return spec
sys.meta_path.insert(0, After())
from seatkit.cli import main
mark("import seatkit.cli")
import seatkit.cli as cli
pm = cli.plugin_manager
def plugin_manager(ctx):
    out = pm(ctx)
    mark("plugins")
    return out
cli.plugin_manager = plugin_manager
sys.argv = ["seatkit", "build", *sys.argv[1:]]
main()
"""

#: The phases printed: (name, the checkpoint that ends it).
PHASES = [
    ("import seatkit.cli", "import seatkit.cli"),
    ("the command's imports", "the command's imports"),
    ("plugin manager", "plugin manager"),
    ("registry", "plugins"),
    ("recipe", "recipe"),
    ("to the first stage", "first stage"),
]


def one_run(python: str, argv: list[str], env: dict, cwd: str) -> dict:
    """{phase: CPU s} of one run, with ``total``, ``gc``, ``collections`` and ``modules``.

    Run in ``cwd``, not here: ``python -c`` imports from its working folder
    first, and a checkout's ``seatkit/`` there would stand in for the
    install's.
    """
    done = subprocess.run([python, "-c", _DRIVER, *argv], capture_output=True, text=True, env=env, cwd=cwd)
    if done.returncode != 0 or not done.stdout.strip():
        sys.exit(f"{python}: the build did not reach its first stage: {done.stderr[-2000:]}")
    marks = {what: (cpu, gc_cpu, collections, modules) for what, cpu, gc_cpu, collections, modules in json.loads(done.stdout)}
    out, before = {}, 0.0
    for name, mark in PHASES:
        cpu = marks[mark][0]
        out[name] = cpu - before
        before = cpu
    out["total"] = before
    out["gc"], out["collections"], out["modules"] = marks["first stage"][1:]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=8, help="runs of each version (default 8)")
    ap.add_argument("--old", help="the Python of an install of the previous code (omit: this code only)")
    ap.add_argument("--new", default=sys.executable, help="the Python of the code measured (default: this one)")
    ap.add_argument("--template", default="chair")
    ap.add_argument("extra", nargs="*", help="more flags for seatkit build")
    args = ap.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.setdefault("SEATKIT_HELPERS", "on")
    sides = {"new": args.new, **({"old": args.old} if args.old else {})}
    results: dict[str, list[dict]] = {k: [] for k in sides}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(-1, args.runs):  # -1: bytecode written, disk caches warm
            order = list(sides) if i % 2 else list(sides)[::-1]
            for side in order:
                argv = ["-q", "--template", args.template, "--out", str(Path(tmp) / f"{side}{i}"), "--overwrite", *args.extra]
                run = one_run(sides[side], argv, env, tmp)
                if i >= 0:
                    results[side].append(run)
    print(f"main process CPU before the first stage of seatkit build --template {args.template}: median of {args.runs} runs (SEATKIT_HELPERS={env['SEATKIT_HELPERS']})")
    print(f"{'':26}" + "".join(f"{side:>10}" for side in sides))
    for name in [p for p, _ in PHASES] + ["total", "gc", "collections", "modules"]:
        cells = []
        for side in sides:
            m = statistics.median(r[name] for r in results[side])
            cells.append(f"{m:9.0f} " if name in ("collections", "modules") else f"{m:8.3f} s")
        label = {"gc": "  of which garbage collection", "collections": "  collections", "modules": "  modules imported"}.get(name, name)
        print(f"{label:26}" + "".join(cells))
    if args.old:
        ratios = [n["total"] / o["total"] for n, o in zip(results["new"], results["old"])]
        print(f"new/old total per run: median {statistics.median(ratios):.2f}x ({', '.join(f'{r:.2f}' for r in ratios)})")


if __name__ == "__main__":
    main()
