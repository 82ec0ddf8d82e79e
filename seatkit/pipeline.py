"""One build, stage by stage, as the data flow in docs/architecture.md reads.

    recipe -> bodies -> pressure -> template -> refiners -> surface -> exporters

:func:`build` is a pure function of its recipe: the inputs are a mapping or a
file, the plugin manager is built fresh unless one is passed, and the result
(:class:`~seatkit.model.BuildResult`) holds only picklable data. Output files
are written into a staging folder beside the target and moved into place only
when every exporter has succeeded, so an interrupted build leaves no output
folder that looks complete.

Where the platform forks safely, the work is split over forked child
processes (:mod:`seatkit.parallel`; docs/architecture.md, "Processes of one
build"): the baseline is fitted beside our refiners, an export worker
prepares and runs the exporters that import big libraries (:class:`_Exports`).
Threads would not do: the stages hold the GIL most of the time.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import shutil
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from seatkit.errors import SeatkitError, UnsupportedPoseError
from seatkit.io import mark_complete, write_text_atomic
from seatkit.model import Body, BuildResult
from seatkit.recipe import check_recipe, load_recipe

#: Niceness added to the build's helper processes (the baseline, the export
#: worker): on two cores three runnable processes would otherwise slow the
#: main process, whose stages are the critical path; the helpers have slack
#: (the baseline is done long before our evaluation needs it, the export
#: worker waits for the design). Only matters when the cores are short.
BACKGROUND_NICE = 5

#: Default gap between neighbours when people are placed automatically, m.
DEFAULT_SEAT_GAP = 0.15

Progress = Callable[[str], None]


def _noop(_stage: str) -> None:
    return None


class _Timer:
    def __init__(self, progress: Progress):
        self.timings: dict[str, float] = {}
        self._progress = progress

    @contextmanager
    def stage(self, name: str):
        self._progress(name)
        start = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - start


def total_seconds(timings: Mapping[str, float]) -> float:
    """A build's wall time from its stage timings.

    Stages marked ``(parallel)`` ran on another process or thread during
    the others and are left out.
    """
    return float(sum(v for k, v in timings.items() if not str(k).endswith("(parallel)")))


def recipe_id(recipe: Mapping) -> str:
    """A short stable hash of a recipe (identifies a run's inputs)."""
    text = json.dumps(recipe, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def make_bodies(recipe: Mapping, registry) -> list[Body]:
    """Pose every person of the recipe and place them in seat order.

    Explicit ``offset`` entries are used as given (metres). Otherwise, with
    several people, they are placed side by side along +X, left to right in
    seat order, their bounding boxes ``placement.gap`` apart (default
    :data:`DEFAULT_SEAT_GAP`), the group centred on x = 0.
    """
    from seatkit.body import load_pose

    bodies: list[Body] = []
    for entry in recipe["bodies"]:
        model = registry.get("body_model", entry["model"])
        rig = model.make_body(params=entry["params"])
        pose = load_pose(entry["pose"], frame=entry.get("frame", 0), rig=rig, dirs=registry.pose_dirs)
        bodies.append(model.pose(rig, pose, ground=True))
    offsets = [e.get("offset") for e in recipe["bodies"]]
    if all(o is not None for o in offsets):
        placed = [b.translated(o) for b, o in zip(bodies, offsets)]
        check_overlap(placed)
        return placed
    if any(o is not None for o in offsets):
        msg = "bodies: give an offset for every person or for none (automatic spacing)"
        raise SeatkitError(msg)
    if len(bodies) == 1:
        return bodies
    gap = float(recipe.get("placement", {}).get("gap", DEFAULT_SEAT_GAP))
    placed, x = [], 0.0
    for b in bodies:
        lo, hi = b.vertices[:, 0].min(), b.vertices[:, 0].max()
        placed.append(b.translated([x - lo, 0.0, 0.0]))
        x += (hi - lo) + gap
    centre = 0.5 * (placed[0].vertices[:, 0].min() + placed[-1].vertices[:, 0].max())
    return [b.translated([-centre, 0.0, 0.0]) for b in placed]


#: Two people closer than this anywhere overlap, m.
MIN_PERSON_GAP = 0.01


def check_overlap(bodies: list[Body]) -> None:
    """Refuse people who overlap (closer than :data:`MIN_PERSON_GAP`), naming them."""
    from scipy.spatial import cKDTree

    for i in range(len(bodies)):
        for j in range(i + 1, len(bodies)):
            a, b = bodies[i], bodies[j]
            lo = np.maximum(a.vertices.min(0), b.vertices.min(0)) - MIN_PERSON_GAP
            hi = np.minimum(a.vertices.max(0), b.vertices.max(0)) + MIN_PERSON_GAP
            if np.any(lo > hi):
                continue  # bounding boxes apart
            near = cKDTree(b.vertices, balanced_tree=False, compact_nodes=False).query(a.vertices, distance_upper_bound=MIN_PERSON_GAP)[0]
            if np.isfinite(near).any():
                msg = (
                    f"person {i + 1} ({a.name}) and person {j + 1} ({b.name}) overlap: their bodies come within "
                    f"{MIN_PERSON_GAP * 100:.0f} cm of each other; move them apart with bodies[].offset or use automatic spacing"
                )
                raise SeatkitError(msg)


def solve_importance(recipe: Mapping, bodies, registry) -> list:
    """Each person's pressure "supported everywhere" (the importance map), with the recipe's settings."""
    p = recipe["pressure"]
    solver = registry.get("pressure_solver", p["solver"])
    return [
        solver.solve(body, lam=p["lambda"], mu=p["mu"], exclude=p.get("exclude"), options=p.get("options") or {})
        for body in bodies
    ]


def _versions() -> dict:
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for dist in ("seatkit", "numpy", "scipy", "pluggy", "qpsolvers", "piqp", "usd-core", "trimesh"):
        try:
            out[dist] = md.version(dist)
        except md.PackageNotFoundError:
            pass
    return out


def _jsonable(value):
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return _jsonable(value.item())
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    return value


def _finish_output(staging: Path, target: Path, *, overwrite: bool) -> None:
    """Move a finished staging folder onto ``target``.

    A previous seatkit run in ``target`` is replaced; a folder with other
    files is refused unless ``overwrite``.
    """
    from seatkit.output import check_writable

    if target.exists():
        check_writable(target, overwrite=overwrite)  # checked before the design too (seatkit.output.claim_output)
        trash = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
        os.replace(target, trash / target.name)
        os.replace(staging, target)
        shutil.rmtree(trash, ignore_errors=True)
    else:
        os.replace(staging, target)


#: Longest default output folder name; longer ones end in a hash of the whole name.
MAX_DESIGN_NAME = 96


def design_name(recipe: Mapping) -> str:
    """A folder name that tells one design from another: template, then each person.

    Each person is their ``name`` if the recipe gives one, else their pose
    (a library name, or a pose file's stem, with ``-frameN`` for a BVH),
    followed by the body when it is not the default (``-default-female``,
    a body file's stem) and the mass when one is given (``-60kg``); people
    are joined by ``+`` in seat order::

        chair-upright-sitting
        chair-reclined-sitting-default-female-60kg
        bench-upright-sitting+reclined-sitting+crossed-legs-knees

    Other body parameters add a short hash of them, so that two designs
    for different bodies never share a default folder.
    """
    from seatkit.recipe import DEFAULT_BODY_MODEL, looks_like_path

    people = []
    for entry in recipe["bodies"]:
        if entry.get("name"):
            people.append(str(entry["name"]))
            continue
        pose = str(entry["pose"])
        part = Path(pose).stem if looks_like_path(pose) else pose
        if pose.lower().endswith(".bvh"):
            part += f"-frame{int(entry.get('frame') or 0)}"
        params = dict(entry.get("params") or {})
        model = entry.get("model", DEFAULT_BODY_MODEL)
        if model == "file":
            part += "-" + Path(str(params.pop("path", "body"))).stem
        elif model != DEFAULT_BODY_MODEL:
            part += f"-{model}"
        mass = params.pop("mass", None)
        if isinstance(mass, (int, float)):
            part += f"-{float(mass):g}kg"
        if params:
            part += "-" + hashlib.sha256(json.dumps(params, sort_keys=True, default=str).encode()).hexdigest()[:6]
        people.append(part)
    name = f"{recipe['template']}-{'+'.join(people)}"
    name = "".join(c if c.isalnum() or c in "-_.+" else "-" for c in name).strip("-.") or "design"
    if len(name) > MAX_DESIGN_NAME:
        digest = hashlib.sha256(name.encode()).hexdigest()[:8]
        name = f"{name[: MAX_DESIGN_NAME - 9]}-{digest}"
    return name


def output_target(recipe: Mapping) -> Path:
    """The output folder of a recipe (default ``seatkit-out/`` + :func:`design_name`)."""
    return Path(recipe["output"] or Path("seatkit-out") / design_name(recipe))


def _save_unsupported(error: UnsupportedPoseError, recipe: Mapping) -> None:
    """Write what could and could not be supported beside the output folder.

    The file is ``<output>-unsupported.json`` (not inside the folder: no
    design was made, so no output folder is created); its path is appended
    to the error's message.
    """
    target = output_target(recipe)
    path = target.parent / f"{target.name}-unsupported.json"
    data = {
        "error": str(error),
        "unsupported_parts": error.parts,
        "diagnostics": _jsonable(error.diagnostics),
        "recipe": _jsonable(dict(recipe)),
    }
    write_text_atomic(path, json.dumps(data, indent=1, default=str) + "\n")
    error.args = (f"{error}; diagnostics saved to {path}",)


def fit_baseline(recipe: Mapping, bodies, pressures, registry, segments) -> dict:
    """Fit and evaluate the baseline design of a recipe (default ``flat-patch``).

    The baseline (what Sit & Relax starts from) is fitted to the same bodies,
    asked to support the same body segments as our cage (a baseline template
    that declares a ``segments`` parameter gets them), refined by the
    recipe's ``evaluate.baseline_refiners`` (default ``catmull-clark-fit``,
    the Sit & Relax surface fit), and evaluated the same way
    (:mod:`seatkit.evaluate`).

    Returns
    -------
    dict
        ``control_mesh``, ``surface``, ``metrics`` (per person),
        ``contact_pressures`` and ``seconds``.
    """
    from seatkit.evaluate import evaluate_design
    from seatkit.skeleton import SEGMENTS
    from seatkit.subdivision import limit_surface

    start = time.perf_counter()
    ev, p = recipe["evaluate"], recipe["pressure"]
    template = registry.get("template", ev["baseline"])
    params = {"segments": [SEGMENTS[s] for s in segments]} if "segments" in getattr(template, "parameters", ()) else {}
    base = template.fit(bodies, pressures, params=params, seed=recipe["seed"])
    from seatkit.recipe import DEFAULT_BASELINE_REFINERS

    # a design.npz written before evaluate.baseline_refiners existed: the default
    refs = ev.get("baseline_refiners", [{"name": n, "params": {}} for n in DEFAULT_BASELINE_REFINERS])
    for ref in refs:
        params = ref["params"]
        if ref["name"] == "catmull-clark-fit" and "surface_limit" not in params:
            # the baseline is measured, not delivered: its penetration is reported, never refused
            params = {**params, "surface_limit": 0.0}
        base = registry.get("refiner", ref["name"]).refine(base, bodies, pressures, params=params)
    surface = limit_surface(base, level=recipe["surface_level"])
    solver = registry.get("pressure_solver", p["solver"])
    metrics, fields = evaluate_design(
        bodies, pressures, surface, solver=solver, support_distance=ev["support_distance"], pressure_settings=p, segments=segments
    )
    return {
        "control_mesh": base,
        "surface": surface,
        "metrics": metrics,
        "contact_pressures": fields,
        "seconds": time.perf_counter() - start,
    }


def evaluate_result(result: BuildResult, registry, timer: "_Timer | None" = None, *, baseline=None) -> None:
    """Fill ``result.metrics`` with the paper's Table 1 figures, ours and the baseline's.

    Parameters
    ----------
    baseline : dict or seatkit.parallel.Background, optional
        The result of :func:`fit_baseline` (or the background work computing
        it while our refiners ran); computed here when not given and the
        recipe asks for a baseline.
    """
    from seatkit.dimensions import support_dimensions
    from seatkit.evaluate import design_segments, evaluate_design
    from seatkit.skeleton import SEGMENTS

    timer = timer or _Timer(_noop)
    recipe = result.recipe
    ev = recipe["evaluate"]
    p = recipe["pressure"]
    solver = registry.get("pressure_solver", p["solver"])
    segments = design_segments(result.control_mesh)
    with timer.stage("evaluate"):
        ours, fields = evaluate_design(
            result.bodies,
            result.pressures,
            result.surface,
            solver=solver,
            support_distance=ev["support_distance"],
            pressure_settings=p,
            segments=segments,
        )
    metrics = {
        "support_distance_m": ev["support_distance"],
        "supported_segments": [SEGMENTS[s] for s in segments],
        "ours": ours,
        "dimensions": support_dimensions(result.bodies, fields),
    }
    result.extra["contact_pressures"] = fields
    if ev.get("baseline"):
        with timer.stage("baseline (wait)"):
            if baseline is None:
                baseline = fit_baseline(recipe, result.bodies, result.pressures, registry, segments)
            elif hasattr(baseline, "result"):
                baseline = baseline.result()
        timer.timings["baseline (parallel)"] = baseline["seconds"]
        metrics["baseline_template"] = ev["baseline"]
        metrics["baseline"] = baseline["metrics"]
        result.extra["baseline"] = {k: baseline[k] for k in ("control_mesh", "surface", "contact_pressures")}
    result.metrics = metrics


def build(
    recipe,
    *,
    pm=None,
    progress: Progress | None = None,
    write: bool = True,
    overwrite: bool = False,
    processes: bool | None = None,
) -> BuildResult:
    """Run one build.

    Parameters
    ----------
    recipe : mapping, path or None
        A recipe (see :mod:`seatkit.recipe`); a mapping is validated like a
        file. Use :func:`seatkit.recipe.apply_overrides` for flag overrides.
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
        Use forked child processes (default where the platform forks
        safely, see :mod:`seatkit.parallel`): the baseline is fitted truly
        in parallel with our refiners, an export worker prepares and runs
        the exporters that import big libraries, and exporters may split
        their work (:func:`seatkit.parallel.forking`). ``False`` keeps the
        build in one process (the baseline on a thread), for callers that
        already keep every core busy (batch workers). The files and results
        are the same either way.

    Returns
    -------
    BuildResult
    """
    from threadpoolctl import threadpool_limits

    from seatkit.parallel import can_fork, forking_allowed

    # Every numerical step here works on small dense blocks or sparse
    # matrices: multithreaded BLAS only adds contention (SLSQP became 10-20x
    # slower with OpenBLAS threads spinning on 2 busy cores), and the build's
    # processes (ours, the baseline, the exports) already use both cores.
    processes = can_fork() if processes is None else bool(processes)
    with threadpool_limits(limits=1), forking_allowed(processes):
        return _build(recipe, pm=pm, progress=progress, write=write, overwrite=overwrite, processes=processes)


def _build(recipe, *, pm, progress, write, overwrite, processes) -> BuildResult:
    from seatkit.plugins import get_plugin_manager

    if isinstance(recipe, Mapping) and "bodies" in recipe and "pressure" in recipe and "refiners" in recipe and all(isinstance(r, dict) for r in recipe["refiners"]):
        # already normalised (from load_recipe/apply_overrides)
        recipe, document = dict(recipe), None
    else:
        recipe, document = load_recipe(recipe)
    pm = pm if pm is not None else get_plugin_manager()
    registry = pm.registry
    progress = progress or _noop
    timer = _Timer(progress)

    with timer.stage("check"):
        check_recipe(recipe, registry, document=document)

    exporters = [registry.get("exporter", name) for name in recipe["exporters"]] if write else []
    # Hold the output folder from before the design to the final rename
    # (seatkit.output): a second build into it, or a folder that cannot be
    # written, is refused now rather than after the whole design; what a
    # killed build left beside it is cleaned up.
    with _claim(recipe, write=write, overwrite=overwrite), _Exports(exporters, processes=processes) as exports:
        result = _design(recipe, registry, timer, write=write, processes=processes)
        if write:
            _write(result, exports, timer, overwrite=overwrite)
    return result


def _claim(recipe: Mapping, *, write: bool, overwrite: bool):
    from contextlib import nullcontext

    from seatkit.output import claim_output

    return claim_output(output_target(recipe), overwrite=overwrite) if write else nullcontext()


def _design(recipe, registry, timer: _Timer, *, write: bool, processes: bool) -> BuildResult:
    """The stages from the bodies to the evaluation: the build's result, nothing written."""
    with timer.stage("bodies"):
        bodies = make_bodies(recipe, registry)

    with timer.stage("pressure"):
        pressures = solve_importance(recipe, bodies, registry)

    with timer.stage("template"):
        template = registry.get("template", recipe["template"])
        try:
            initial = template.fit(bodies, pressures, params=recipe["template_params"], seed=recipe["seed"])
        except UnsupportedPoseError as e:
            if write:
                _save_unsupported(e, recipe)
            raise

    # The baseline depends only on the bodies and the segments our cage
    # supports: fit it in a forked child process (a thread where the platform
    # cannot fork, see seatkit.parallel) while our refiners run.
    baseline = None
    if recipe["evaluate"]["enabled"] and recipe["evaluate"]["baseline"]:
        from seatkit.evaluate import design_segments
        from seatkit.parallel import Background

        segments = design_segments(initial)
        baseline = Background(
            fit_baseline, recipe, bodies, pressures, registry, segments, name="baseline", process=processes, nice=BACKGROUND_NICE
        )
    try:
        mesh = initial
        for ref in recipe["refiners"]:
            with timer.stage(f"refine:{ref['name']}"):
                refiner = registry.get("refiner", ref["name"])
                mesh = refiner.refine(mesh, bodies, pressures, params=ref["params"])

        with timer.stage("surface"):
            from seatkit.subdivision import limit_surface

            surface = limit_surface(mesh, level=recipe["surface_level"])

        result = BuildResult(
            recipe=recipe,
            bodies=bodies,
            pressures=pressures,
            initial_mesh=initial,
            control_mesh=mesh,
            surface=surface,
            timings=timer.timings,
        )
        if recipe["evaluate"]["enabled"]:
            evaluate_result(result, registry, timer, baseline=baseline)
        if recipe.get("structure", {}).get("enabled"):
            with timer.stage("structure"):
                from seatkit.structure.build import run_structure

                run_structure(result)
    finally:
        if baseline is not None:
            baseline.close()
    return result


def _export_worker(receive, exporters: list) -> list[dict] | None:
    """The export worker's job (see :class:`_Exports`): get ready, wait for the result, export."""
    for exporter in exporters:
        exporter.prepare()
    job = receive()
    if job is None:  # the build ended without writing
        return None
    result, directory = job
    return [exporter.export(result, directory) for exporter in exporters]


class _Exports:
    """The exporters of a build, some of them run by a worker process.

    Exporters whose ``prepare_ahead`` is true (the built-in ones whose time
    goes mostly into importing a big library: usd-core, trimesh, plotly) are
    run by a worker process forked when the build starts. It
    calls their ``prepare()`` while the main process computes the design (on
    2 cores the second one is idle until the template is fitted), receives
    the result when the design is done and writes its files into the same
    staging folder while the main process runs the other exporters (the PNG
    report, design.npz). Without forked processes (``processes=False``, see
    :mod:`seatkit.parallel`) every exporter runs in the main process, in
    recipe order.
    """

    def __init__(self, exporters: list, *, processes: bool):
        from seatkit.parallel import Background, can_fork

        self.exporters = list(exporters)
        ahead = [i for i, e in enumerate(self.exporters) if e.prepare_ahead]
        self.ahead = ahead if processes and can_fork() else []
        self.worker = None
        if self.ahead:
            self.worker = Background(
                _export_worker, [self.exporters[i] for i in self.ahead], name="export", inbox=True, nice=BACKGROUND_NICE
            )

    def run(self, result: BuildResult, directory: Path) -> list[dict]:
        """Every exporter's ``{role: path}``, in recipe order.

        Raises the first error of the main process's exporters, else the
        worker's; either way the worker has ended (and written nothing more)
        when this returns or raises.
        """
        out: dict[int, dict] = {}
        if self.worker is not None:
            self.worker.send((result, directory))
        try:
            for i, exporter in enumerate(self.exporters):
                if i not in self.ahead:
                    exporter.prepare()
                    out[i] = exporter.export(result, directory)
        except BaseException:
            self.close()
            raise
        if self.worker is not None:
            out.update(zip(self.ahead, self.worker.result()))
        return [out[i] for i in range(len(self.exporters))]

    def close(self) -> None:
        """Stop the worker if it still runs (the build failed or wrote nothing)."""
        if self.worker is not None:
            self.worker.close()

    def __enter__(self) -> "_Exports":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _write(result: BuildResult, exports: _Exports, timer: _Timer, *, overwrite: bool) -> None:
    """Export into a staging folder, write report.json, move the folder into place."""
    recipe, mesh, pressures = result.recipe, result.control_mesh, result.pressures
    target = output_target(recipe)
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.staging-", dir=target.parent))
    except OSError as e:
        from seatkit.output import output_error

        raise output_error(e, target) from e
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(staging, 0o777 & ~mask)  # mkdtemp makes 0700 folders
    try:
        with timer.stage("export"):
            files: dict[str, Path] = {}
            for written in exports.run(result, staging):
                for role, path in written.items():
                    files[role] = target / Path(path).name
        result.timings = timer.timings
        html_report = staging / "report.html"
        if "report_html" in files and html_report.exists():
            from seatkit.export.report import finish_report_html

            finish_report_html(html_report, timer.timings)  # the export stage's time, and the total
        report = {
            "seatkit_run": recipe_id(recipe),
            "recipe": _jsonable(recipe),
            "versions": _versions(),
            "timings_s": _jsonable(timer.timings),
            "control_mesh": {
                "vertices": int(len(mesh.vertices)),
                "faces": int(len(mesh.faces)),
                "meta": _jsonable(mesh.meta),
            },
            "pressure": [
                {
                    "status": pf.status,
                    "solve_seconds": pf.solve_seconds,
                    "max_pressure_pa": float(pf.pressure.max()),
                    "max_joint_moment_nm": float(np.linalg.norm(pf.joint_moment, axis=1).max()),
                }
                for pf in pressures
            ],
            "metrics": _jsonable(result.metrics),
            "files": {k: Path(v).name for k, v in files.items()},
        }
        write_text_atomic(staging / "report.json", json.dumps(report, indent=1) + "\n")
        files["report"] = target / "report.json"
        mark_complete(staging, run_id=recipe_id(recipe), files=files)
        _finish_output(staging, target, overwrite=overwrite)
    except OSError as e:  # a full disk, a folder made read-only meanwhile: one line naming the folder
        from seatkit.output import output_error

        shutil.rmtree(staging, ignore_errors=True)
        raise output_error(e, target) from e
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    result.files = {k: str(v) for k, v in files.items()}
    result.extra["output"] = str(target)


def write_result(result: BuildResult, registry, *, overwrite: bool = False, progress: Progress | None = None) -> None:
    """Write a result computed with ``build(write=False)``, as ``build(write=True)`` would have.

    Runs the recipe's exporters in this process into a staging folder, writes
    ``report.json`` and moves the folder to ``recipe["output"]``; fills
    ``result.files`` and ``result.extra["output"]``. For callers that show a
    design first and write its files later (``seatkit serve``).
    """
    timer = _Timer(progress or _noop)
    timer.timings = dict(result.timings)
    exporters = [registry.get("exporter", name) for name in result.recipe["exporters"]]
    with _Exports(exporters, processes=False) as exports:
        _write(result, exports, timer, overwrite=overwrite)
