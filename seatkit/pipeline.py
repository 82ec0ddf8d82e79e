"""One build, as the data flow in docs/architecture.md reads.

    recipe -> bodies -> pressure -> template -> refiners -> surface -> evaluation -> exporters

:func:`build` is a pure function of its recipe: the inputs are a mapping or a
file, the plugin manager is built fresh unless one is passed, and the result
(:class:`~seatkit.model.BuildResult`) holds only picklable data. The stages
are :mod:`seatkit.stages`; the output folder (its name, the hold on it, the
staging folder moved into place only when every exporter has succeeded) is
:mod:`seatkit.output`; ``report.json`` is the ``report-json`` exporter, run
last (:mod:`seatkit.export.report_json`).

With ``processes`` (the default) two helper processes of
:mod:`seatkit.workers` (standard ``concurrent.futures`` pools) start with the
build: one fits the baseline beside our refiners, one imports the big
exporter libraries while the design is computed and runs those exporters
beside the others (docs/architecture.md, "Processes of one build").
"""

from __future__ import annotations

import itertools
from concurrent.futures import wait
from contextlib import ExitStack, contextmanager, nullcontext
from pathlib import Path
from typing import Iterator

from seatkit.errors import UnsupportedPoseError
from seatkit.export.report_json import REPORT_EXPORTER
from seatkit.model import BuildResult
from seatkit.output import MAX_DESIGN_NAME, claim_output, design_name, output_target, save_unsupported, staging_folder
from seatkit.recipe import Recipe, check_recipe, load_recipe, recipe_id
from seatkit.search import bind as bind_search
from seatkit.search import search, template_cages
from seatkit.stages import (
    StageTimer,
    baseline_components,
    evaluate_result,
    fit_baseline,
    fit_baseline_with,
    make_bodies,
    place_bodies,
    refine,
    solve_importance,
    total_seconds,
)

__all__ = [
    "MAX_DESIGN_NAME",
    "build",
    "design_name",
    "evaluate_result",
    "fit_baseline",
    "make_bodies",
    "output_target",
    "own_designs",
    "seated_importance",
    "recipe_id",
    "solve_importance",
    "total_seconds",
    "write_result",
]


def build(recipe, *, pm=None, progress=None, write: bool = True, overwrite: bool = False, processes: bool | None = None) -> BuildResult:
    """Run one build.

    Parameters
    ----------
    recipe : Recipe, mapping, path or None
        A :class:`~seatkit.recipe.Recipe` (checked already: used as it is),
        or a recipe mapping or file (see :mod:`seatkit.recipe`), validated
        and checked here; None for the defaults. Use
        :func:`seatkit.recipe.apply_overrides` for flag overrides.
    pm : SeatkitPluginManager, optional
        The plugin manager; default a fresh one (:func:`seatkit.plugins.get_plugin_manager`).
    progress : callable, optional
        Called with each stage's name as it starts.
    write : bool
        Run the exporters into ``recipe["output"]``; without it nothing is
        written.
    overwrite : bool
        Allow replacing an output folder that seatkit did not write.
    processes : bool, optional
        Fit the baseline and run the exporters that import big libraries in
        helper processes (:mod:`seatkit.workers`). Multiprocessing imports
        the caller's main script again in them, so pass ``True`` only from
        a script whose build runs under ``if __name__ == "__main__":`` (the
        ``seatkit`` command does). Default: only where nothing would be
        imported again (the REPL, a notebook, ``python -c``,
        :func:`seatkit.workers.main_is_import_safe`). ``False`` runs
        everything in this process, in sequence, for callers that already
        keep every core busy (batch workers) or run builds on threads
        (``seatkit serve``). The files and results are the same either way.
    """
    from threadpoolctl import threadpool_limits

    from seatkit.plugins import get_plugin_manager

    # Every numerical step works on small dense blocks or sparse matrices:
    # multithreaded BLAS only adds contention (SLSQP became 10-20x slower
    # with OpenBLAS threads spinning on 2 busy cores).
    if processes is None:
        from seatkit.workers import main_is_import_safe

        processes = main_is_import_safe()
    with threadpool_limits(limits=1):
        registry = (pm if pm is not None else get_plugin_manager()).registry
        timer = StageTimer(progress)
        if not isinstance(recipe, Recipe):  # a Recipe is checked already (seatkit.recipe.check_recipe)
            with timer.stage("check"):
                data, document = load_recipe(recipe)
                recipe = check_recipe(data, registry, document=document)
        exporters = _exporters(recipe, registry) if write else []
        with ExitStack() as helpers:
            # Hold the output folder from before the design to the final
            # rename: a second build into it, or a folder that cannot be
            # written, is refused now rather than after the whole design.
            helpers.enter_context(claim_output(output_target(recipe), overwrite=overwrite) if write else nullcontext())
            # one context for both, chosen before the first starts (workers.helper_context)
            context = _helper_context() if processes else None
            export_helper = _helper(helpers, "export", [e for e in exporters if e.prepare_ahead], processes, context)
            baseline_helper = _helper(helpers, "baseline", [], processes and _wants_baseline(recipe), context)
            # the exporters' work that needs only the bodies and their importance, in a helper
            # idle then (the baseline's, until the template is fitted; else the export worker)
            early = _Early(exporters, baseline_helper or export_helper)
            # the exporters' work that needs only the design, in the export worker
            # beside the evaluation (not where that worker computes the interface
            # pressure: a recipe without a baseline)
            beside = export_helper if baseline_helper is not None or not _wants_interface(recipe) else None
            designed = _Designed(exporters, beside, early, lambda: helpers.enter_context(_staging(output_target(recipe), overwrite, (export_helper, baseline_helper))))
            result = _design(recipe, registry, timer, write=write, baseline_helper=baseline_helper, export_helper=export_helper, early=early.submit, designed=designed.submit)
            if write:
                _write(result, exporters, registry, timer, overwrite=overwrite, helper=export_helper, spare=baseline_helper, early=early, designed=designed)
    return result


def _exporters(recipe, registry) -> list:
    """The recipe's exporters but ``report-json`` (run last by :func:`_write`), each guarded (:class:`seatkit.plugins.Guarded`).

    An exporter that declares ``options`` (:mod:`seatkit.options`) is called
    ``export(result, directory, options=...)`` with the recipe's ``params``
    for it checked and its defaults filled in.
    """
    from seatkit.params import component_params

    template = registry.get("template", recipe["template"])
    given = recipe.get("exporter_params") or {}
    out = []
    for name in recipe["exporters"]:
        if name == REPORT_EXPORTER:
            continue
        declared = getattr(registry.get("exporter", name), "options", None)
        keywords = None
        if declared:
            options = component_params(f"exporter {name!r}", declared, given.get(name), where=("exporters", name, "params"))
            keywords = {"export": {"options": options}}
        out.append(registry.guarded("exporter", name, template=template, keywords=keywords))
    return out


def _wants_baseline(recipe) -> bool:
    return bool(recipe["evaluate"]["enabled"] and recipe["evaluate"]["baseline"])


def _wants_interface(recipe) -> bool:
    return bool(recipe["evaluate"]["enabled"] and recipe["evaluate"].get("interface_pressure", True))


def _helper_context():
    from seatkit.workers import helper_context

    return helper_context()


def _helper(stack: ExitStack, what: str, exporters: list, wanted: bool, context=None):
    """A helper process closed with the build (:class:`seatkit.workers.Helper`), or None."""
    if not wanted or (what == "export" and not exporters):
        return None
    from seatkit.workers import Helper

    return stack.enter_context(Helper(what, exporters, context))


def _design(recipe, registry, timer: StageTimer, *, write: bool, baseline_helper, export_helper=None, early=None, designed=None, recline_offset: float = 0.0, recline_builds: int = 1) -> BuildResult:
    """The stages from the bodies to the evaluation: the build's result, nothing written.

    ``early(recipe, bodies, pressures)`` is called once the importance
    pressures are solved (:class:`_Early`); ``designed(result, baseline,
    complete)`` once the design is made (its cages and surface), before it
    is evaluated, with the baseline's design where it is fitted by then
    (:class:`_Designed`).

    With a backrest recline set (the ``seat`` step's ``recline``), a built
    backrest more than :data:`~seatkit.template.seat.RECLINE_TOLERANCE_DEG`
    from it is built again with the back reclined by the difference (the
    backrest follows the back within a few degrees, not exactly), at most
    :data:`~seatkit.template.seat.RECLINE_BUILDS` builds, and refused if it
    still misses.
    """
    with timer.stage("bodies"):
        bodies, frames = place_bodies(recipe, registry, recline_offset=recline_offset)

    with timer.stage("pressure"):
        pressures = solve_importance(recipe, bodies, registry)
    if recipe.get("sitters"):  # one seat for several sitters: each pelvis on one seat pan (seatkit.sitters)
        with timer.stage("pressure"):
            bodies, pressures, moves = _seat_sitters(recipe, bodies, pressures, registry)
    if early is not None:
        early(recipe, bodies, pressures)

    template = registry.get("template", recipe["template"])
    if recipe.get("sitters"):  # one seat for several sitters (seatkit.sitters)
        from seatkit.sitters import SharedTemplate

        template = SharedTemplate(template)
    with timer.stage("template"):
        cages = template_cages(template, bodies, pressures, params=recipe["template_params"], seed=recipe["seed"])
        try:
            initial = next(cages)
        except UnsupportedPoseError as e:
            if write:
                save_unsupported(e, recipe)
            raise

    # The baseline depends only on the bodies and the segments our cage
    # supports: it is fitted in its helper process while our refiners run.
    baseline = None
    if baseline_helper is not None:
        from seatkit.evaluate import design_segments

        segments = design_segments(initial)
        job = baseline_helper.submit(fit_baseline_with, recipe, bodies, pressures, baseline_components(recipe, registry), segments)

        def baseline():
            return baseline_helper.result(job)

    # which cage becomes the design: the design search (seatkit.search)
    refiners = [(r["name"], registry.guarded("refiner", r["name"], template=template), r["params"]) for r in recipe["refiners"]]
    sources = bind_search(template, bodies, pressures, params=recipe["template_params"], seed=recipe["seed"], first=itertools.chain([initial], cages))
    fit_last = bool(refiners) and refiners[-1][0] == "catmull-clark-fit"
    from seatkit.template.seat import refined_seat

    def refit(cage):  # the surface fit again, around what a designer set (the seat depth's front edge)
        return refine(cage, refiners[-1:], bodies, pressures, timer)

    def refined(cage):  # a candidate refined, with the seat depth set put on it (seatkit.template.seat)
        return refined_seat(recipe, registry, refine(cage, refiners, bodies, pressures, timer), bodies, refit if fit_last else None)

    outcome = search(sources, refined, bodies, fit_last=fit_last, stage=timer.stage)
    initial, mesh = outcome.design()
    from seatkit.refine.ccfit import final_depths
    from seatkit.template.seat import check_design, seat_design

    bodies, initial, mesh, moved = seat_design(recipe, registry, bodies, initial, mesh, depths=final_depths)  # a seat height set is the built design's
    if moved:
        baseline = None  # fitted for the bodies before the move: fitted again in evaluate_result
    if baseline is not None and design_segments(initial) != segments:
        baseline = None  # a later cage supports other segments: its baseline is fitted here, in evaluate_result

    with timer.stage("surface"):
        from seatkit.subdivision import limit_surface

        surface = limit_surface(mesh, level=recipe["surface_level"])
    check_design(recipe, registry, bodies, surface, mesh)  # a dimension the designer set is the built design's
    from seatkit.template.seat import RECLINE_BUILDS, RECLINE_TOLERANCE_DEG, recline_miss

    recline = recline_miss(recipe, registry, bodies, surface)
    if recline is not None and abs(recline[0] - recline[1]) > RECLINE_TOLERANCE_DEG:
        got, want = recline
        if recline_builds < RECLINE_BUILDS:
            again = recline_offset + want - got
            return _design(recipe, registry, timer, write=write, baseline_helper=baseline_helper, export_helper=export_helper, early=early, designed=designed, recline_offset=again, recline_builds=recline_builds + 1)
        from seatkit.errors import RecipeError

        raise RecipeError(f"template_params.steps.seat.recline: the built backrest reclines {got:.1f} deg, not {want:g} deg (within {RECLINE_TOLERANCE_DEG:g} deg), after the trunk was reclined to meet it; allowed: -10 to 50 deg, try one nearer the pose's own")

    result = BuildResult(recipe, bodies, pressures, initial_mesh=initial, control_mesh=mesh, surface=surface, timings=timer.timings, frames=frames)
    if designed is not None:
        _hand_over(designed, result, baseline, job if baseline is not None else None)
    if recipe["evaluate"]["enabled"]:
        # the interface pressure in the baseline's helper when it is idle; in the
        # export worker only where there is no baseline (a busy baseline helper
        # means a busy machine, where this process computes it sooner itself)
        evaluate_result(result, registry, timer, baseline=baseline, helper=baseline_helper if baseline_helper is not None else export_helper)
        if recipe.get("sitters"):
            with timer.stage("own designs"):  # the cost of sharing: each sitter's design alone (seatkit.sitters)
                from seatkit.sitters import sharing_metrics

                own = own_designs(recipe, registry)
                result.metrics["sharing"] = sharing_metrics(result.metrics["ours"], own, [b.name for b in bodies], [m for m, _, _ in moves], [k for _, k, _ in moves], [h for _, _, h in moves])
    if recipe.get("structure", {}).get("enabled"):
        with timer.stage("structure"):
            from seatkit.structure.build import run_structure

            run_structure(result)
    return result


def _hand_over(designed, result: BuildResult, baseline, job) -> None:
    """``designed(result, baseline, complete)``: ``complete`` where the recipe compares with no baseline or its baseline is fitted by now (``baseline``, its design), else False."""
    if not _wants_baseline(result.recipe):
        designed(result, None, True)
        return
    base = None
    if baseline is not None and job.done():  # else fitted again in the evaluation, or not yet
        try:
            base = baseline()
        except Exception:  # noqa: BLE001  (the evaluation raises it, where it did before)
            base = None
    designed(result, base, base is not None)


def _seat_sitters(recipe, bodies, pressures, registry) -> tuple[list, list, list]:
    """The sitters on one seat pan (those lowered with their legs re-posed, their importance solved again on the new pose; those lifted off the floor solved again without it), and each sitter's move, knee extension and hip flexion (:mod:`seatkit.sitters`)."""
    from seatkit.sitters import align_sitters, sitter_posers

    posers = sitter_posers(recipe, registry) if len(bodies) > 1 else None
    seated, moves, knees, hips = align_sitters(bodies, pressures, posers, floor_distance=recipe["evaluate"]["support_distance"])
    reposed = [k > 0.0 or h > 0.0 for k, h in zip(knees, hips)]
    if any(reposed):
        fresh = iter(solve_importance(recipe, [b for b, r in zip(seated, reposed) if r], registry))
        pressures = [next(fresh) if r else p for p, r in zip(pressures, reposed)]
    return seated, seated_importance(recipe, seated, pressures, registry), list(zip(moves, knees, hips))


def seated_importance(recipe, bodies, pressures, registry) -> list:
    """``pressures`` of a shared design's seated sitters with those lifted off the floor solved again (:func:`seatkit.sitters.lifted_importance`); as they are for other recipes."""
    if not recipe.get("sitters"):
        return list(pressures)
    from seatkit.sitters import lifted_importance

    p = recipe["pressure"]
    solver = registry.get("pressure_solver", p["solver"])

    def solve(body, contact):
        return solver.solve(body, contact=contact, lam=p["lambda"], mu=p["mu"], exclude=p.get("exclude"), options=p.get("options") or {})

    return lifted_importance(bodies, pressures, solve, floor_distance=recipe["evaluate"]["support_distance"])


def design_only(recipe: Recipe, registry) -> BuildResult:
    """The design and evaluation of a checked recipe, in this process, nothing written (no baseline helper)."""
    return _design(recipe, registry, StageTimer(), write=False, baseline_helper=None)


def own_designs(recipe: Recipe, registry) -> list[dict]:
    """Each sitter's figures on a design made for that sitter alone (same template, refiners, seed), or the reason there is none.

    Returns one dict per sitter: ``ours`` (the Table 1 figures of
    :func:`seatkit.evaluate.evaluate_person`) or ``refused`` (why the
    template or the search refused the sitter alone).
    """
    from seatkit.errors import SeatkitError
    from seatkit.recipe import check_recipe

    out = []
    for entry in recipe["bodies"]:
        alone = recipe.to_dict() if hasattr(recipe, "to_dict") else dict(recipe)
        alone.pop("sitters", None)
        alone["bodies"] = [dict(entry)]
        alone["evaluate"] = {**alone["evaluate"], "baseline": None, "interface_pressure": False}
        alone.pop("structure", None)
        try:
            result = design_only(check_recipe(alone, registry), registry)
        except SeatkitError as e:
            out.append({"refused": str(e).splitlines()[0]})
            continue
        out.append({"ours": result.metrics["ours"][0]})
    return out


class _Early:
    """The exporters' work that needs only the bodies and their importance pressure (``export_early``).

    :meth:`submit` hands it to ``helper`` as soon as the pressures are
    solved, so that it runs while the design is computed; :meth:`payload`
    gives an exporter what its ``export_early`` returned, as its ``early``
    keyword at export time (None without a helper, or where it failed: the
    exporter then does that work itself). The exporter checks that the
    payload shows the bodies it exports (a seat height set, or sitters,
    move them after the pressures are solved).
    """

    def __init__(self, exporters: list, helper):
        self._exporters = {i: e for i, e in enumerate(exporters) if helper is not None and hasattr(e, "export_early")}
        self._helper = helper
        self._jobs: dict = {}

    def submit(self, recipe, bodies: list, pressures: list) -> None:
        if self._jobs or not self._exporters:
            return
        partial = BuildResult(recipe, list(bodies), list(pressures))
        self._jobs = {i: self._helper.submit(_run_early, e, partial) for i, e in self._exporters.items()}

    def payload(self, index: int, *, wait: bool = True):
        """What exporter ``index``'s ``export_early`` returned; None where it did not run, failed, or (without ``wait``) is not done yet."""
        job = self._jobs.get(index)
        if job is None or (not wait and not job.done()):
            return None
        try:
            return self._helper.result(job)
        except Exception:  # noqa: BLE001  (the exporter does the work itself, and reports its own error)
            return None

    def keywords(self, index: int, *, wait: bool = True) -> dict:
        """``{"early": payload}`` for an exporter that has ``export_early``, else nothing."""
        return {"early": self.payload(index, wait=wait)} if index in self._exporters else {}


def _design_tasks(exporters: list, *, baseline: bool = True) -> list[tuple[int, int | None]]:
    """``(exporter index, part)`` of the work that needs only the design: exporters with ``design_only`` (whole: part None) and the ``design_parts`` of the others; without ``baseline``, not that of the exporters that read the baseline's design too (``reads_baseline``)."""
    tasks = []
    for i, exporter in enumerate(exporters):
        if not baseline and getattr(exporter, "reads_baseline", False):
            continue
        if getattr(exporter, "design_only", False):
            tasks.append((i, None))
        elif _parts(exporter) != [None]:
            tasks += [(i, part) for part in _parts(exporter) if part in tuple(getattr(exporter, "design_parts", ()) or ())]
    return tasks


class _Designed:
    """The exporters' work that needs only the design (``design_only``, ``design_parts``), run beside its evaluation.

    :meth:`submit` is called with the build's result once its cages and
    surface are made, before the evaluation, with the baseline's design
    where the recipe compares with one and it is fitted by then
    (``complete``; if it is not, the work of the exporters that read it,
    ``reads_baseline``, is left to the export stage): it opens the
    staging folder (``open_staging``) and hands that work to ``helper``
    (the export worker, which by then has nothing else to do but the
    ``export_early`` work it may have been given), on a copy of the designs
    alone, so that the files are written while this process evaluates the
    design. :meth:`files` gives them to the export stage, which does the
    rest. Without a helper nothing is handed over and the export stage
    does it all, as in one process.
    """

    def __init__(self, exporters: list, helper, early: _Early, open_staging):
        self._exporters = exporters
        self._helper = helper
        self._early = early
        self._open = open_staging
        self.tasks: list[tuple[int, int | None]] = []
        self.staging: Path | None = None
        self._job = None

    def submit(self, result: BuildResult, baseline=None, complete: bool = True) -> None:
        tasks = _design_tasks(self._exporters, baseline=complete) if self._helper is not None else []
        if self._job is not None or not tasks:
            return
        self.staging = self._open()
        design = BuildResult(result.recipe, list(result.bodies), list(result.pressures), initial_mesh=result.initial_mesh, control_mesh=result.control_mesh, surface=result.surface, frames=list(result.frames or []), baseline=baseline)
        exporters = [self._exporters[i] for i, _ in tasks]
        keywords = [self._early.keywords(i, wait=False) for i, _ in tasks]  # what is drawn by now: no wait here
        self._job = self._helper.submit(_run_design, exporters, design, self.staging, [part for _, part in tasks], keywords)
        self.tasks = tasks

    def jobs(self) -> list:
        """The job handed to the helper, if any (to wait for)."""
        return [self._job] if self._job is not None else []

    def files(self) -> dict:
        """``{(exporter index, part): its files}`` of the work handed over (its error re-raised)."""
        if self._job is None:
            return {}
        return dict(zip(self.tasks, self._helper.result(self._job)))


def _run_design(exporters: list, result: BuildResult, directory: Path, parts: list, keywords: list) -> list[dict]:
    """The design-only work of :class:`_Designed` (a helper's job): each exporter whole (part None) or one part, its ``{role: path}``."""
    capture = _capture_result(result)
    return [_run_part(exporter, result, directory, capture, part, kw) for exporter, part, kw in zip(exporters, parts, keywords)]


@contextmanager
def _staging(target: Path, overwrite: bool, helpers) -> Iterator[Path]:
    """The build's staging folder (:func:`seatkit.output.staging_folder`), opened before the export stage: on an error the helpers are stopped before it is removed, so that none writes into it after."""
    with staging_folder(target, overwrite=overwrite) as staging:
        try:
            yield staging
        except BaseException:
            for helper in helpers:
                if helper is not None:
                    helper.close(stop=True)
            raise


def _run_early(exporter, result: BuildResult):
    """An exporter's ``export_early`` on a result that holds the recipe, the bodies and their importance only (a helper's job)."""
    exporter.prepare()
    return exporter.export_early(result)


def _run_exporters(exporters: list, result: BuildResult, directory: Path, capture: BuildResult | None = None, keywords: list | None = None) -> list[dict]:
    """Each exporter's ``{role: path}``, in order (the export helper's job); ``keywords``: each one's ``early`` keyword (:class:`_Early`)."""
    keywords = keywords or [{}] * len(exporters)
    return [exporter.export(_exported(exporter, result, capture), directory, **kw) for exporter, kw in zip(exporters, keywords)]


def _run_part(exporter, result: BuildResult, directory: Path, capture: BuildResult | None, part: int | None, early: dict | None = None) -> dict:
    """An exporter prepared and run, whole (``part`` None) or one part of it (``export_part``): its ``{role: path}``; ``early``: its ``early`` keyword (:class:`_Early`)."""
    exporter.prepare()
    exported = _exported(exporter, result, capture)
    kw = early or {}
    return exporter.export(exported, directory, **kw) if part is None else exporter.export_part(exported, directory, part, **kw)


def _parts(exporter) -> list:
    """The parts a ``runs_apart`` exporter's work divides into (``parts`` and ``export_part``), or ``[None]``: whole."""
    n = int(getattr(exporter, "parts", 1) or 1)
    return list(range(n)) if n > 1 and hasattr(exporter, "export_part") else [None]


def _joined(exporter, files: list[dict]) -> dict:
    """The files of an exporter's parts as its ``export`` would list them (``join_parts``, else in part order)."""
    if len(files) == 1:
        return files[0]
    join = getattr(exporter, "join_parts", None)
    return join(files) if join is not None else {role: path for f in files for role, path in f.items()}


def _exported(exporter, result: BuildResult, capture: BuildResult | None) -> BuildResult:
    """The result ``exporter`` writes: in the capture's frame (``capture``) for the geometry exporters when the recipe asks."""
    from seatkit.body.frame import CAPTURE_FRAME_EXPORTERS

    return capture if capture is not None and exporter.name in CAPTURE_FRAME_EXPORTERS else result


def _capture_result(result: BuildResult) -> BuildResult | None:
    """The result in the capture's frame when the recipe's ``export_frame`` is ``capture``, else None."""
    if result.recipe.get("export_frame") != "capture" or not result.frames:
        return None
    from seatkit.body.frame import result_in_capture_frame

    return result_in_capture_frame(result)


def _write(result: BuildResult, exporters: list, registry, timer: StageTimer, *, overwrite: bool, helper=None, spare=None, early: _Early | None = None, designed: _Designed | None = None) -> None:
    """Run the exporters into a staging folder, report.json last, and move the folder into place.

    With an export ``helper``, the exporters whose ``prepare_ahead`` is true
    run there (on a pickled copy of the result) while this process runs the
    others. With a ``spare`` helper that is idle (the baseline's, its work
    done), the exporters whose ``runs_apart`` is true (costly, with nothing
    to import ahead: the report's pictures) are run apart: whole, or in the
    parts they declare (``parts``, ``export_part``), each in turn in the
    spare helper, the export helper (after its own exporters) and this
    process (after the others). The files of all are listed in recipe
    order, an exporter's parts as its ``export`` lists them (``join_parts``).
    An exporter with ``export_early`` gets what it returned (``early``).
    The work ``designed`` handed to the export helper before the evaluation
    (:class:`_Designed`: the exporters with ``design_only``, the
    ``design_parts`` of others) is not done again: its files are in the
    staging folder it opened, which this stage goes on with; where it held
    a part, this process takes the parts left before the export helper
    does.
    """
    from seatkit.io import mark_complete

    early = early if early is not None else _Early([], None)
    handed = set(designed.tasks) if designed is not None else set()
    whole = {i for i, part in handed if part is None}  # done at design time, whole
    target = output_target(result.recipe)
    report = registry.get("exporter", REPORT_EXPORTER)
    ahead = [i for i, e in enumerate(exporters) if e.prepare_ahead and not any(t[0] == i for t in handed)] if helper is not None else []
    idle = spare if spare is not None and spare.idle() else None
    # run apart: with an idle spare helper those that say so; an exporter with parts done at design time, always (its other parts)
    apart = [
        i for i, e in enumerate(exporters)
        if i not in ahead and i not in whole and ((idle is not None and getattr(e, "runs_apart", False)) or any((i, part) in handed for part in _parts(e)))
    ]
    capture = _capture_result(result)
    staged = designed.staging if designed is not None else None
    with nullcontext(staged) if staged is not None else staging_folder(target, overwrite=overwrite) as staging:
        with timer.stage("export"):
            job = helper.submit(_run_exporters, [exporters[i] for i in ahead], result, staging, capture, [early.keywords(i) for i in ahead]) if ahead else None
            # the parts run apart, in turn: the spare helper, the export helper, this process (this
            # process before the export helper when that one has drawn a part beside the evaluation);
            # without an idle spare helper (a busy machine), all in this process
            others = [helper] if helper is not None else []
            drew = any(part is not None for _, part in handed)
            places = [None] if idle is None else [idle, None, *others] if drew else [idle, *others, None]
            left = [(i, part) for i in apart for part in _parts(exporters[i]) if (i, part) not in handed]
            tasks = [(i, part, places[k % len(places)]) for k, (i, part) in enumerate(left)]
            remote = [(i, part, place, place.submit(_run_part, exporters[i], result, staging, capture, part, early.keywords(i))) for i, part, place in tasks if place is not None]
            done: dict[int, dict] = {i: {} for i in apart}  # exporter index -> {part: its files}
            written = {}
            try:
                for i, exporter in enumerate(exporters):
                    if i not in ahead and i not in apart and i not in whole:
                        written[i] = _run_part(exporter, result, staging, capture, None, early.keywords(i))
                for i, part, place in tasks:
                    if place is None:
                        done[i][part] = _run_part(exporters[i], result, staging, capture, part, early.keywords(i))
                report.prepare()  # while the helpers finish
            finally:  # the helpers' files are in the staging folder before it is moved or deleted
                wait([job] * (job is not None) + [r[3] for r in remote] + (designed.jobs() if designed is not None else []))
            if job is not None:
                written.update(zip(ahead, helper.result(job)))
            for (i, part), files in (designed.files() if designed is not None else {}).items():
                if part is None:
                    written[i] = files
                else:
                    done[i][part] = files
            for i, part, place, part_job in remote:
                done[i][part] = place.result(part_job)
            for i in apart:
                written[i] = _joined(exporters[i], [done[i][part] for part in _parts(exporters[i])])
            for place in (helper, spare):  # nothing more for them: they end beside report.json
                if place is not None:
                    place.release()
        files = {role: target / Path(path).name for i in range(len(exporters)) for role, path in written[i].items()}
        result.timings, result.files = timer.timings, files
        written_report = report.export(result, staging)
        files.update({role: target / Path(path).name for role, path in written_report.items()})
        mark_complete(staging, run_id=recipe_id(result.recipe), files=files)
    result.files = {k: str(v) for k, v in files.items()}
    result.output = str(target)


def write_result(result: BuildResult, registry, *, overwrite: bool = False, progress=None) -> None:
    """Write a result computed with ``build(write=False)``, as ``build(write=True)`` would have.

    Runs the recipe's exporters in this process into a staging folder, writes
    ``report.json`` and moves the folder to ``recipe["output"]``; fills
    ``result.files`` and ``result.output``. For callers that show a design
    first and write its files later (``seatkit serve``).
    """
    timer = StageTimer(progress)
    timer.timings = dict(result.timings)
    _write(result, _exporters(result.recipe, registry), registry, timer, overwrite=overwrite)
