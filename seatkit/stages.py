"""The stages of one build, each a function of the recipe and what came before.

:mod:`seatkit.pipeline` calls them in order (body -> pressure -> template ->
refiners -> surface -> evaluation); ``seatkit serve`` and ``seatkit
evaluate`` call some of them on their own. Each looks its components up in
the plugin registry by the names the recipe gives.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Callable, Iterator, Mapping

import numpy as np

from seatkit.errors import SeatkitError
from seatkit.model import Baseline, Body, BuildResult, total_seconds

__all__ = [
    "DEFAULT_SEAT_GAP",
    "MIN_PERSON_GAP",
    "StageTimer",
    "check_overlap",
    "evaluate_result",
    "baseline_components",
    "fit_baseline",
    "fit_baseline_with",
    "make_bodies",
    "refine",
    "solve_importance",
    "total_seconds",
]

#: Default gap between neighbours when people are placed automatically, m.
DEFAULT_SEAT_GAP = 0.15

#: Two people closer than this anywhere overlap, m.
MIN_PERSON_GAP = 0.01

Progress = Callable[[str], None]


def _noop(_stage: str) -> None:
    return None


class StageTimer:
    """Seconds per stage of a build (``timings``), telling ``progress`` each stage's name as it starts."""

    def __init__(self, progress: Progress | None = None):
        self.timings: dict[str, float] = {}
        self._progress = progress or _noop

    @contextmanager
    def stage(self, name: str):
        self._progress(name)
        start = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - start


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


def refine(mesh, refiners, bodies, pressures, timer: StageTimer | None = None):
    """``mesh`` after each ``(name, refiner, params)`` in turn, each timed as ``refine:NAME``."""
    from seatkit.errors import SolverError

    timer = timer or StageTimer()
    for i, (name, refiner, params) in enumerate(refiners):
        with timer.stage(f"refine:{name}"):
            try:
                mesh = refiner.refine(mesh, bodies, pressures, params=params)
            except SolverError as e:
                e.refiner_index = i  # where a repair of its refusal continues (refine_first_accepted)
                raise
    return mesh


#: Cages of the template refined in all, at most, before a build is refused
#: because its refiners refuse them (each one more costs a template start and
#: the refiners again: about a second for the chair).
MAX_REFINED_CAGES = 4


def template_cages(template, bodies, pressures, *, params, seed, last_resort: bool = False) -> Iterator:
    """The template's valid cages in its order of preference.

    Its ``fits`` where it has one (:meth:`seatkit.template.YamlTemplate.fits`:
    one cage per start that gives a valid one), else the single cage of its
    ``fit``. Lazy: a cage is fitted only when it is asked for. With
    ``last_resort``, the cages of its ``last_resort_fits``
    (:meth:`seatkit.template.YamlTemplate.last_resort_fits`), none for a
    template without one.
    """
    if last_resort:
        fits = getattr(template, "last_resort_fits", None)
        if fits is not None:
            yield from fits(bodies, pressures, params=params, seed=seed)
        return
    fits = getattr(template, "fits", None)
    if fits is None:
        yield template.fit(bodies, pressures, params=params, seed=seed)
    else:
        yield from fits(bodies, pressures, params=params, seed=seed)


def refine_first_accepted(cages: Iterator, cage, refiners, bodies, pressures, timer: StageTimer | None = None, *, walls=None, last_resort=None) -> tuple:
    """``(cage, refined)``: the first of the template's cages that the refiners accept, and it refined.

    ``cage`` is the template's first cage, ``cages`` the rest of
    :func:`template_cages`. A refiner refuses a cage by raising
    :class:`~seatkit.errors.SolverError`: the surface fit's guarantee (its
    surface would reach more than 5 mm into the person, or the person into
    the furniture), or a fit that cannot be solved. Another start of the
    template is another design of the same pose, so the next cage is
    refined instead, up to :data:`MAX_REFINED_CAGES` in all; a cage that is
    refused by every refiner run, or a template with no other cage, raises
    the first refusal. The refusals of earlier cages are kept in the accepted
    cage's ``meta["refiner_refusals"]`` (and the refined cage's). The seed
    thus picks among designs the whole build accepts, not only the template.

    When every cage is refused, a refusal that carries a last local repair
    (the surface fit's, :class:`seatkit.refine.ccfit.SurfaceLimitRefusal`:
    its refit closest to the limit with the offending spots pushed away
    from the body) is tried, in the cages' order; the first repaired cage
    that the rest of the refiners accept is the design (its refusal in
    ``meta["repaired_refusal"]``). Only a build that would otherwise be
    refused runs a repair: every design that builds without one is the same.

    Then ``walls`` (a callable ``(cage, refused control points) -> cage or
    None``: the template's :meth:`~seatkit.template.YamlTemplate.walls_against`)
    is asked, cage by cage in their order, for the cage rebuilt with walls
    inside the hands the refused surface (a refusal's ``closest``) encloses,
    and that cage is refined, its own refusal repaired locally as above; the
    first accepted is the design (``meta["fit_attempts"]["walls_against_refusal"]``,
    and the refusal it answers in ``meta["walls_against"]``). It too runs
    only in a build that would otherwise be refused
    (docs/templates.md, "Walls against the refused surface"); a ``walls``
    that raises :class:`~seatkit.errors.UnsupportedPoseError` offers nothing.

    Last, when none of those is accepted either, ``last_resort`` (a callable
    giving an iterator of further cages: the template's last-resort cages,
    :func:`template_cages` with ``last_resort``) is asked for up to
    :data:`MAX_REFINED_CAGES` more cages, refined, and then repaired, the
    same way; the first accepted is the design (``meta["fit_attempts"]
    ["last_resort"]``; docs/templates.md, "Last resort: feet on the leg
    rest"). The walls come first: they answer what a refused surface
    names, where the last resort changes the whole cage. A template
    that refuses every last-resort start, or has none, leaves the refusal
    as it was: the first cage's.
    """
    from seatkit.errors import SolverError, UnsupportedPoseError

    timer = timer or StageTimer()
    refused: list = []  # (cage, its refusal)

    def accepted(cage, refined, repaired=None, against=None):
        if against is not None:
            cage.meta["walls_against"] = refined.meta["walls_against"] = str(against)
        if refused:
            refusals = [str(e) for _, e in refused]
            cage.meta["refiner_refusals"] = refusals
            refined.meta["refiner_refusals"] = list(refusals)
        if repaired is not None:
            refined.meta["repaired_refusal"] = str(repaired)
        return cage, refined

    def first_accepted(cage, cages) -> tuple | None:
        """The first of ``cage`` and ``cages`` the refiners accept, else the first repaired one; None when none is."""
        start = len(refused)
        while True:
            try:
                return accepted(cage, refine(cage, refiners, bodies, pressures, timer))
            except SolverError as e:
                refused.append((cage, e))
            nxt = None
            if len(refused) - start < MAX_REFINED_CAGES:
                with timer.stage("template"):
                    nxt = next(cages, None)
            if nxt is None:
                break
            cage = nxt
        # every cage refused: the refusals' last local repairs, in the cages' order
        for cage, e in refused[start:]:
            refined = _repaired(e, refiners, bodies, pressures, timer)
            if refined is not None:
                return accepted(cage, refined, repaired=e)
        return None

    found = first_accepted(cage, cages)
    if found is not None:
        return found
    # then the cages again with walls inside the hands their refused surfaces enclose
    for cage, e in list(refused) if walls is not None else ():
        closest = getattr(e, "closest", None)
        if closest is None:
            continue
        with timer.stage("template"):
            try:
                offered = walls(cage, closest.vertices)
            except UnsupportedPoseError:
                continue  # a template that refuses the start again offers nothing: the refusal stays the first cage's
        if offered is None:
            continue
        try:
            return accepted(offered, refine(offered, refiners, bodies, pressures, timer), against=e)
        except SolverError as again:
            refined = _repaired(again, refiners, bodies, pressures, timer)
            if refined is not None:
                return accepted(offered, refined, repaired=again, against=e)
    if last_resort is not None:
        # the template's last-resort cages (the chair's feet on its shanks' planes), only now
        with timer.stage("template"):
            more = last_resort()
            try:
                cage = next(more, None)
            except UnsupportedPoseError:
                cage = None  # every last-resort start refused by the template's checks
        if cage is not None:
            found = first_accepted(cage, _until_refused(more))
            if found is not None:
                return found
    first = refused[0][1]
    if getattr(first, "repair", None) is not None:
        first = SolverError(*first.args)  # the refusal as before: a SolverError, its repair let go
    raise first from None


def _repaired(refusal, refiners, bodies, pressures, timer: StageTimer):
    """The refusal's last local repair (its ``repair()``), refined by the refiners after the one that refused; None when it fails."""
    from seatkit.errors import SolverError

    repair = getattr(refusal, "repair", None)
    if repair is None:
        return None
    with timer.stage(f"refine:{refiners[refusal.refiner_index][0]}"):
        repaired = repair()
    if repaired is None:
        return None
    try:
        return refine(repaired, refiners[refusal.refiner_index + 1 :], bodies, pressures, timer)
    except SolverError:
        return None


def _until_refused(cages: Iterator) -> Iterator:
    """``cages`` until the template refuses the rest (an :class:`~seatkit.errors.UnsupportedPoseError` ends them)."""
    from seatkit.errors import UnsupportedPoseError

    try:
        yield from cages
    except UnsupportedPoseError:
        return


def baseline_components(recipe: Mapping, registry) -> tuple:
    """What :func:`fit_baseline` needs from the registry: the template, refiners and pressure solver.

    Looked up by the caller (they are small and picklable; the registry is
    not), so that the baseline can be fitted in a helper process.
    """
    from seatkit.recipe import DEFAULT_BASELINE_REFINERS

    ev = recipe["evaluate"]
    # a design.npz written before evaluate.baseline_refiners existed: the default
    refs = ev.get("baseline_refiners", [{"name": n, "params": {}} for n in DEFAULT_BASELINE_REFINERS])
    refiners = []
    for ref in refs:
        params = ref["params"]
        if ref["name"] == "catmull-clark-fit" and "surface_limit" not in params:
            # the baseline is measured, not delivered: its penetration is reported, never refused
            params = {**params, "surface_limit": 0.0}
        refiners.append((ref["name"], registry.get("refiner", ref["name"]), params))
    solver = registry.get("pressure_solver", recipe["pressure"]["solver"])
    return registry.get("template", ev["baseline"]), refiners, solver


def fit_baseline(recipe: Mapping, bodies, pressures, registry, segments) -> Baseline:
    """Fit and evaluate the baseline design of a recipe (default ``flat-patch``).

    The baseline (what Sit & Relax starts from) is fitted to the same bodies,
    asked to support the same body segments as our cage (a baseline template
    that declares a ``segments`` parameter gets them), refined by the
    recipe's ``evaluate.baseline_refiners`` (default ``catmull-clark-fit``,
    the Sit & Relax surface fit), and evaluated the same way
    (:mod:`seatkit.evaluate`).
    """
    return fit_baseline_with(recipe, bodies, pressures, baseline_components(recipe, registry), segments)


def fit_baseline_with(recipe: Mapping, bodies, pressures, components: tuple, segments) -> Baseline:
    """:func:`fit_baseline` with its components (:func:`baseline_components`) looked up already."""
    from seatkit.evaluate import evaluate_design
    from seatkit.skeleton import SEGMENTS
    from seatkit.subdivision import limit_surface

    start = time.perf_counter()
    ev, p = recipe["evaluate"], recipe["pressure"]
    template, refiners, solver = components
    params = {"segments": [SEGMENTS[s] for s in segments]} if "segments" in getattr(template, "parameters", ()) else {}
    base = template.fit(bodies, pressures, params=params, seed=recipe["seed"])
    base = refine(base, refiners, bodies, pressures)
    surface = limit_surface(base, level=recipe["surface_level"])
    metrics, fields = evaluate_design(
        bodies, pressures, surface, solver=solver, support_distance=ev["support_distance"], pressure_settings=p, segments=segments
    )
    return Baseline(ev["baseline"], base, surface, metrics, fields, time.perf_counter() - start)


def evaluate_result(
    result: BuildResult, registry, timer: StageTimer | None = None, *, baseline: Callable[[], Baseline] | None = None
) -> None:
    """Fill ``result.metrics`` with the paper's Table 1 figures, ours and the baseline's.

    Sets ``result.contact_pressures`` and, when the recipe asks for a
    baseline, ``result.baseline``.

    Parameters
    ----------
    baseline : callable, optional
        Returns the baseline design (waiting for the helper process that
        fits it while our refiners run, :mod:`seatkit.workers`); without
        it the baseline is fitted here, when the recipe asks for one.
    """
    from seatkit.dimensions import support_dimensions
    from seatkit.evaluate import design_segments, evaluate_design
    from seatkit.skeleton import SEGMENTS

    timer = timer or StageTimer()
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
    result.contact_pressures = fields
    if ev.get("interface_pressure", True):
        from seatkit.evaluate import evaluate_interface

        with timer.stage("interface pressure"):
            figures, result.interface_pressures = evaluate_interface(result.bodies, result.surface, mu=p.get("mu"))
        metrics["interface"] = figures
    if ev.get("baseline"):
        with timer.stage("baseline (wait)"):
            if baseline is None:
                base = fit_baseline(recipe, result.bodies, result.pressures, registry, segments)
            else:
                base = baseline()
        timer.timings["baseline (parallel)"] = base.seconds
        metrics["baseline_template"] = ev["baseline"]
        metrics["baseline"] = base.metrics
        result.baseline = base
    result.metrics = metrics
