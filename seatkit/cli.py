"""The ``seatkit`` command line: parse, call the library, print.

Commands live here (``build``, ``plugins``, ``templates``) and in the modules
of :mod:`seatkit.commands`, each of which defines ``register(app)``; every
module there is picked up automatically, in name order.

A user error (:class:`~seatkit.errors.SeatkitError`) is printed as
``seatkit: error: <message>`` on stderr with exit code 1; ``--debug`` shows
the traceback instead. Any other exception is a bug and shows its traceback.
"""

from __future__ import annotations

import atexit
import contextlib
import copy
import gc
import importlib
import inspect
import json
import os
import pkgutil
import sys
import threading
from pathlib import Path
from typing import List, Optional, Sequence, get_args, get_origin

import typer
import typer.core
import typer.main
import typer.models

from seatkit.errors import SeatkitError
from seatkit.messages import one_line
from seatkit.workers import cpu_snapshot

#: The machine's CPU ticks when this program started: ``seatkit build``
#: measures the idle time since (its own start-up) to decide whether helper
#: processes pay (:func:`seatkit.workers.helpers_pay`).
_STARTED = cpu_snapshot()


#: What a reader of :class:`_PlainCoercion` returns for a value it leaves to typer.
_TYPER = object()


def _plain_str(value, param, ctx):
    return value if type(value) is str else _TYPER


def _plain_strs(value, param, ctx):
    if isinstance(value, (list, tuple)) and all(type(v) is str for v in value):
        return list(value)
    return _TYPER


def _plain_path(check):
    def read(value, param, ctx):
        if type(value) is not str:
            return _TYPER
        # typer's own checks (exists, dir_okay, readable, ...) of the Path
        # its pydantic adapter makes of the text (``Path(value)``)
        return check(Path(value), param.type_descriptor.parameter_info, path_type=Path, param=param, ctx=ctx)

    return read


class _PlainCoercion:
    """Stands in for a typer parameter's ``get_runtime_param``: plain values read directly, the rest by typer.

    typer 0.2x reads every option's value through a pydantic
    ``TypeAdapter`` that it builds for each option a command has, given or
    not (``None`` included): pydantic's import and those adapters were
    0.07-0.1 s of CPU before every ``seatkit build``. A value that is not
    given (``None``: typer makes it ``None``, or ``()`` for a repeatable
    option), a text option's text, a repeatable text option's texts and a
    path option's path (typer's own checks of it kept) come out here as
    typer's adapters make them, without pydantic; anything else (numbers,
    choices, a value typer would refuse) goes to typer's own reading, built
    the first time it is needed.
    """

    def __init__(self, read):
        self._read, self._typer = read, None

    def __call__(self):
        return self

    def coerce(self, value, param, ctx):
        if value is None:
            return () if (param.multiple or param.nargs == -1) else None
        out = self._read(value, param, ctx)
        if out is _TYPER:
            if self._typer is None:
                self._typer = type(param).get_runtime_param(param)
            out = self._typer.coerce(value, param=param, ctx=ctx)
        return out


def _typer_reads(value, param, ctx):
    return _TYPER


def _plain_reader(param):
    """How :class:`_PlainCoercion` reads ``param``'s given values, or None: not a typer parameter typer reads through pydantic."""
    descriptor = getattr(param, "type_descriptor", None)
    info = getattr(descriptor, "parameter_info", None)
    if info is None or not hasattr(type(param), "get_runtime_param"):
        return None
    annotation, multi = descriptor.annotation, param.multiple or param.nargs == -1
    if getattr(info, "parser", None) is not None:
        return _typer_reads
    if annotation is str and not multi:
        return _plain_str
    if get_origin(annotation) is list and get_args(annotation) == (str,) and param.multiple:
        return _plain_strs
    if annotation is Path and not multi and getattr(info, "path_type", None) is None:
        try:
            from typer._param_types import coerce_cli_path
        except ImportError:
            return _typer_reads
        return _plain_path(coerce_cli_path)
    return _typer_reads


def _plain_coercion(params) -> None:
    """Each typer parameter of ``params`` read by :class:`_PlainCoercion` (once)."""
    for param in params:
        read = _plain_reader(param)
        if read is not None and "get_runtime_param" not in vars(param):
            param.get_runtime_param = _PlainCoercion(read)


class _PlainParams:
    """A command (or group) whose options and arguments, its help option included, are read by :class:`_PlainCoercion`."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        _plain_coercion(self.params)

    def get_help_option(self, ctx):
        option = super().get_help_option(ctx)
        if option is not None:
            _plain_coercion([option])
        return option


class _SeatkitCommand(_PlainParams, typer.core.TyperCommand):
    """A ``seatkit`` command (every ``app.command()``)."""


class _SeatkitTyper(typer.Typer):
    """``typer.Typer`` whose commands are :class:`_SeatkitCommand` unless they name their own class."""

    def command(self, *args, cls=None, **kwargs):
        return super().command(*args, cls=cls or _SeatkitCommand, **kwargs)


class _SeatkitGroup(_PlainParams, typer.core.TyperGroup):
    """Turns SeatkitError into one line on stderr and exit code 1."""

    def invoke(self, ctx: typer.Context):
        try:
            return super().invoke(ctx)
        except SeatkitError as e:
            if (ctx.obj or {}).get("debug"):
                raise
            # one line of at most MAX_MESSAGE characters, even for an error a
            # plugin made with a str() of its own
            typer.echo(f"seatkit: error: {one_line(str(e))}", err=True)
            ctx.exit(1)
        except KeyboardInterrupt:
            typer.echo("seatkit: interrupted; no partial output was kept", err=True)
            ctx.exit(130)


app = _SeatkitTyper(
    cls=_SeatkitGroup,
    name="seatkit",
    help=(
        "Design body-supporting furniture from a human body in a pose.\n\n"
        "Start with:  seatkit build --template chair   (the default body, upright sitting)\n\n"
        "Then try --pose (see 'seatkit poses'), --body, --recipe FILE.yaml, and "
        "'seatkit templates' / 'seatkit plugins' for what is installed."
    ),
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


@app.callback()
def _main(
    ctx: typer.Context,
    debug: bool = typer.Option(False, "--debug", help="Show the traceback of an error."),
    disable_plugin: List[str] = typer.Option(
        [], "--disable-plugin", metavar="NAME", help="Do not load this plugin (repeatable)."
    ),
) -> None:
    ctx.obj = {"debug": debug, "disabled": tuple(disable_plugin)}


def plugin_manager(ctx: typer.Context):
    """The plugin manager for this invocation (built once, honouring --disable-plugin)."""
    from seatkit.plugins import get_plugin_manager

    root = ctx.find_root()
    obj = root.obj if root.obj is not None else {}
    if "pm" not in obj:
        obj["pm"] = get_plugin_manager(disabled=obj.get("disabled", ()))
        obj["pm"].registry  # noqa: B018 - build it now so that its problems are shown too
        for problem in obj["pm"].problems:
            typer.echo(f"seatkit: warning: {problem}", err=True)
        root.obj = obj
    return obj["pm"]


@contextlib.contextmanager
def _collections_paused():
    """Python's cyclic garbage collector off inside (restored after, as it was): the build's start-up.

    The objects made then are modules, functions, classes and registered
    components that live as long as the process; the few cycles that are
    garbage wait for the collections after the build (:func:`gc.freeze`
    keeps them with the rest until :func:`gc.unfreeze`).
    """
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if collecting:
            gc.enable()


#: The environment variable OpenBLAS reads, as it is loaded, for the size of its thread pool.
_BLAS_THREADS = "OPENBLAS_NUM_THREADS"


@contextlib.contextmanager
def _one_blas_thread():
    """numpy's and scipy's OpenBLAS loaded with one thread by the imports inside, unless numpy is imported already or ``OPENBLAS_NUM_THREADS`` is set.

    The build runs every numerical step on one thread
    (:func:`seatkit.pipeline.build`); each OpenBLAS library otherwise
    starts a pool of one thread per core as it loads, whose threads spin
    idle for a while (0.1-0.15 s of CPU beside the start-up). The
    environment is as it was after the block: the processes the build
    starts (a fork server, an exporter's programs) get the user's. A
    program that goes on after the command keeps those two libraries on
    one thread.
    """
    if "numpy" in sys.modules or _BLAS_THREADS in os.environ:
        yield
        return
    os.environ[_BLAS_THREADS] = "1"
    try:
        yield
    finally:
        os.environ.pop(_BLAS_THREADS, None)


def stderr_console():
    """A rich console on stderr (progress, tables that are not the output)."""
    from rich.console import Console

    return Console(stderr=True)


@app.command()
def build(
    ctx: typer.Context,
    template: Optional[str] = typer.Option(None, "--template", "-t", help="Template name, e.g. chair, bench, flat-patch."),
    recipe: Optional[Path] = typer.Option(None, "--recipe", "-r", help="Recipe YAML; flags given here override it."),
    pose: List[str] = typer.Option([], "--pose", "-p", help="Library pose name, pose YAML or BVH (repeat in seat order)."),
    body: List[str] = typer.Option(
        [], "--body", "-b", help="default-male, default-female, p5-female ... p95-male, a .npz/.glb file, or MODEL:key=value,... (repeatable)."
    ),
    mass: Optional[float] = typer.Option(None, "--mass", help="Body mass in kg (default the body's: 75 default-male, 55 default-female, a preset's)."),
    height: Optional[float] = typer.Option(None, "--height", help="Stature in m (parametric bodies: default-*, p5-female ... p95-male)."),
    frame: Optional[int] = typer.Option(None, "--frame", help="Frame of a BVH pose."),
    sitter: List[str] = typer.Option(
        [], "--sitter", help="BODY:POSE of a person who shares the one seat with the other --sitter people (repeatable; instead of --pose and --body)."
    ),
    refiner: List[str] = typer.Option([], "--refiner", help="Refiner to run, in order (repeatable; replaces the recipe's)."),
    no_refiners: bool = typer.Option(False, "--no-refiners", help="Skip every refiner: export the template's cage."),
    exporter: List[str] = typer.Option([], "--exporter", help="Exporter to run (repeatable; replaces the default set)."),
    solver: Optional[str] = typer.Option(None, "--solver", help="Pressure solver (default qp)."),
    lam: Optional[float] = typer.Option(None, "--lambda", help="Moment/pressure balance (default 0.013; inf = rigid)."),
    mu: Optional[float] = typer.Option(None, "--mu", help="Friction coefficient (default 0.5)."),
    out: Optional[Path] = typer.Option(
        None, "--out", "-o", help="Output folder (default seatkit-out/ and the recipe's name, or the template and poses)."
    ),
    seed: Optional[int] = typer.Option(None, "--seed", help="Random seed (RANSAC); same seed, same files."),
    level: Optional[int] = typer.Option(None, "--level", help="Subdivision level of the exported surface (1-4)."),
    export_frame: Optional[str] = typer.Option(
        None, "--export-frame", help="canonical (default: the person facing +Z, centred) or capture (the geometry files in the capture's own frame; one person)."
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an output folder seatkit did not write."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Print nothing but errors."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON summary on stdout (for scripts)."),
    structure: bool = typer.Option(False, "--structure", help="Analyse the shell's strength (FEM): structure.json/.png, shell.stl."),
    material: Optional[str] = typer.Option(None, "--material", help="Shell material for --structure (default birch-plywood)."),
    thickness: Optional[float] = typer.Option(None, "--thickness", help="Shell thickness in m for --structure (default 0.02)."),
    size_thickness: bool = typer.Option(False, "--size-thickness", help="Find the thinnest shell that keeps --safety-factor and --max-deflection."),
    safety_factor: Optional[float] = typer.Option(None, "--safety-factor", help="Safety factor --size-thickness keeps (default 2)."),
    max_deflection: Optional[float] = typer.Option(None, "--max-deflection", help="Deflection limit in m --size-thickness keeps (default 0.01)."),
    option: List[str] = typer.Option(
        [], "--option", help="STEP.KEY=VALUE: a template step's option, e.g. seat.height=0.55 (repeatable; docs/templates.md lists every step's options)."
    ),
) -> None:
    """Design a support for a body in a pose and write the cage, surface and report.

    Stages: bodies -> pressure -> template -> refiners -> surface -> exporters.
    """
    # no garbage collection while the build starts up (_collections_paused):
    # numpy, scipy, the stages and the plugins make some 100,000 objects
    # the collector tracks, which live as long as the process, and some 160
    # collections walked them (0.08 s of CPU, a tenth of the start-up) to
    # find next to no garbage
    with _collections_paused():
        with _one_blas_thread():  # the stages' imports: numpy, scipy and their OpenBLAS
            from seatkit.pipeline import build as run_build
        from seatkit.recipe import apply_overrides, check_recipe, load_recipe
        from seatkit.workers import helpers_pay, start_fork_server

        # helper processes only with an idle core beside this one, measured
        # over this program's start-up up to here: the stages' imports (numpy,
        # scipy: a few tenths of a second of one core) are the window, long
        # enough for the machine's idle time to tell (seatkit.workers.spare_cores
        # needs 10 clock ticks; the option parsing alone is shorter). The
        # helpers are forks of this process, which has imported the stages, or,
        # where it cannot fork, of a fork server that imports them, started
        # now, beside the plugins and the recipe
        processes = helpers_pay(_STARTED)
        if processes:
            start_fork_server()

        pm = plugin_manager(ctx)
        base, document = load_recipe(recipe)
        merged = apply_overrides(
            base,
            template=template,
            poses=pose or None,
            bodies=body or None,
            mass=mass,
            height=height,
            frame=frame,
            refiners=[] if no_refiners else (refiner or None),
            exporters=exporter or None,
            solver=solver,
            lam=lam,
            mu=mu,
            output=str(out) if out is not None else None,
            seed=seed,
            surface_level=level,
            export_frame=export_frame,
            sitters=sitter or None,
            options=option or None,
        )
        if merged["output"] is None and recipe is not None and not (template or pose or body or sitter or option or mass is not None or frame is not None):
            merged["output"] = str(Path("seatkit-out") / recipe.stem)  # the recipe's design, named after it

        if structure or size_thickness or any(v is not None for v in (material, thickness, safety_factor, max_deflection)):
            from seatkit.structure.build import enable

            enable(merged, material=material, thickness=thickness, size_thickness=size_thickness or None, safety_factor=safety_factor, max_deflection=max_deflection)
        merged = check_recipe(merged, pm.registry, document=document)  # a Recipe: build() takes it as checked
        # what is imported and registered by now outlives the build: its
        # garbage collections need not walk it again (two full collections
        # walked it, 0.06 s of a build's CPU); given back to the collector after
        # the build, for a program that runs more than one command
        gc.freeze()
    try:
        if quiet or as_json:
            result = run_build(merged, pm=pm, overwrite=overwrite, processes=processes)  # the entry point is guarded (seatkit.workers)
        else:
            # the spinner (a thread) starts with the first stage, after the
            # build has forked its helper processes (seatkit.workers)
            status = stderr_console().status("building")

            def progress(stage: str) -> None:
                status.update(f"[bold]{stage}[/]")
                status.start()  # (once: a started spinner ignores it)

            try:
                result = run_build(merged, pm=pm, overwrite=overwrite, processes=processes, progress=progress)
            finally:
                status.stop()
    finally:
        gc.unfreeze()
    summary = {
        "output": result.output,
        "files": result.files,
        "timings_s": result.timings,
        "control_mesh": {"vertices": len(result.control_mesh.vertices), "faces": len(result.control_mesh.faces)},
        "special_cases": result.control_mesh.meta.get("special_cases", []),
        "metrics": result.metrics,
    }
    if as_json:
        typer.echo(json.dumps(summary, indent=1, default=str))
        return
    if quiet:
        return
    from rich.table import Table

    table = Table(title=f"seatkit build: {merged['template']} -> {summary['output']}", show_edge=False)
    table.add_column("stage")
    table.add_column("seconds", justify="right")
    for stage, seconds in result.timings.items():
        table.add_row(stage, f"{seconds:.3f}")
    from seatkit.pipeline import total_seconds

    total = total_seconds(result.timings)  # stages marked "(parallel)" ran beside the others
    table.add_row("[bold]total[/]", f"[bold]{total:.3f}[/]")
    console = stderr_console()
    console.print(table)
    typer.echo(f"wrote {len(result.files)} files to {summary['output']}", err=True)  # one line, never wrapped


@app.command()
def plugins(ctx: typer.Context) -> None:
    """List every plugin: its distribution, version and the components it registers."""
    from rich.console import Console
    from rich.table import Table

    pm = plugin_manager(ctx)
    registry = pm.registry  # builds components, fills infos
    # fits the terminal (80 columns when not a terminal): the components
    # column wraps, one kind of component per line
    table = Table(show_edge=False, show_lines=True)
    table.add_column("plugin", no_wrap=True)
    table.add_column("distribution", overflow="fold")
    table.add_column("version", no_wrap=True)
    table.add_column("components", ratio=1, overflow="fold")
    for name, info in sorted(pm.infos.items()):
        comps = "\n".join(f"{kind.replace('_', ' ')}: {', '.join(names)}" for kind, names in sorted(info.components.items()))
        if info.disabled:
            comps = "disabled (see its problem below)"
        label = f"{name} (built-in)" if info.builtin else name
        table.add_row(label, info.distribution or "-", info.version or "-", comps or "-")
    Console().print(table)
    for problem in pm.problems:
        typer.echo(f"problem: {problem}")
    del registry


@app.command()
def templates(ctx: typer.Context) -> None:
    """List the furniture templates that can be built (seatkit build --template NAME)."""
    from rich.console import Console
    from rich.table import Table

    pm = plugin_manager(ctx)
    table = Table(box=None, show_edge=False, pad_edge=False)  # fits the terminal: descriptions wrap
    table.add_column("template", style="bold", no_wrap=True)
    table.add_column("description", ratio=1)
    table.add_column("plugin", no_wrap=True)
    for name, component, plugin in pm.registry.items("template"):
        table.add_row(name, component.description, plugin)
    Console().print(table)


def _register_command_modules() -> None:
    from seatkit import commands

    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"seatkit.commands.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(app)


_register_command_modules()


def _group_options() -> tuple[set[str], set[str]]:
    """(flags, options that take a value) of the ``seatkit`` group itself (:func:`_main`'s)."""
    flags: set[str] = set()
    valued: set[str] = set()
    for param in inspect.signature(_main).parameters.values():
        info = param.default
        if isinstance(info, typer.models.OptionInfo):
            (flags if isinstance(info.default, bool) else valued).update(info.param_decls)
    return flags, valued


def _command_named(argv: Sequence[str]) -> str | None:
    """The command ``argv`` names after the group's own options; None where it names none, asks for help, or has an option the group does not declare."""
    flags, valued = _group_options()
    i = 0
    while i < len(argv):
        token = argv[i]
        if token in flags:
            i += 1
        elif token in valued:
            i += 2
        elif token.partition("=")[0] in valued:
            i += 1
        elif token.startswith("-"):
            return None
        else:
            return token
    return None


def _app_for(argv: Sequence[str]) -> typer.Typer:
    """``app``, or a copy of it with only the command ``argv`` names.

    typer makes the click command of every command of the app, its options
    and their readers, before it reads the command line: about 10 ms of CPU
    for the thirteen commands ``seatkit build`` does not run. The copy parses
    the command line the same way (the group's options, then the command's);
    where ``argv`` names no command of the app (``--help``, a typo, an
    option the group does not declare) typer gets the whole app, which lists
    and suggests every command.
    """
    name = _command_named(argv)
    named = [info for info in app.registered_commands if (info.name or typer.main.get_command_name(info.callback.__name__)) == name]
    if len(named) != 1 or app.registered_groups:
        return app
    view = copy.copy(app)
    view.registered_commands = named
    return view


def run() -> int | str | None:
    """Run the command ``sys.argv`` names and return its exit status (what it would pass to ``sys.exit``)."""
    try:
        _app_for(sys.argv[1:])(prog_name="seatkit")
    except SystemExit as e:
        return e.code
    return 0


def main() -> None:
    """Console-script entry point: runs the command, then ends the process without tearing the interpreter down.

    Once the command is done, its output is flushed and the exit handlers
    run (``atexit``: multiprocessing's, a plugin's), then the process ends
    (``os._exit``) instead of freeing every module and object one by one,
    which took 0.04-0.06 s of CPU after every build. Where that cannot be
    done as ``sys.exit`` would (another thread still runs, an exit status
    that is a message, standard output that cannot be flushed), the
    process exits the usual way.
    """
    code = run()
    # The process ends next: its long-lived objects (numpy, scipy and the
    # rest, ~100k) need no last garbage collection, which took ~0.08 s of
    # every command's exit where it ends the usual way. Frozen objects are
    # skipped by it. (Not in run(): a program that goes on collects them.)
    gc.freeze()
    if code is None:
        code = 0
    if not isinstance(code, int) or threading.active_count() > 1:
        sys.exit(code)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        sys.exit(code)  # reported as Python reports it
    atexit._run_exitfuncs()
    os._exit(code & 0xFF)


if __name__ == "__main__":  # pragma: no cover
    main()
