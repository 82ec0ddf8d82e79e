"""The stages of one build, each a function of the recipe and what came before.

:mod:`seatkit.pipeline` calls them in order (body -> pressure -> template ->
refiners -> surface -> evaluation); ``seatkit serve`` and ``seatkit
evaluate`` call some of them on their own. Each looks its components up in
the plugin registry by the names the recipe gives.
"""

from __future__ import annotations

import functools
import time
from contextlib import contextmanager
from typing import Callable, Mapping

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
    "place_bodies",
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
    """Pose every person of the recipe, each in the canonical frame, and place them in seat order (:func:`place_bodies`)."""
    return place_bodies(recipe, registry)[0]


def place_bodies(recipe: Mapping, registry, *, recline_offset: float = 0.0) -> tuple[list[Body], list]:
    """Pose every person of the recipe, bring each into the canonical frame, and place them in seat order.

    Each posed body is turned to face +Z and centred
    (:mod:`seatkit.body.frame`: the heading from the pelvis and the
    shoulders, not the capture's root), so a capture gives the same design
    at any heading. Then explicit ``offset`` entries are added as given
    (metres, in that frame). Otherwise, with several people, they are placed
    side by side along +X, left to right in seat order, their bounding boxes
    ``placement.gap`` apart (default :data:`DEFAULT_SEAT_GAP`), the group
    centred on x = 0.

    Returns
    -------
    bodies : list of Body
        In the template's frame, placed.
    frames : list of seatkit.body.frame.CanonicalFrame
        Per person, the move from the capture's frame into the canonical
        one (before the placement; report.json's ``frames``).
    """
    from seatkit.body import load_pose
    from seatkit.body.frame import pose_canonical

    bodies: list[Body] = []
    frames: list = []
    recline = _seat_option(recipe, registry, "recline")
    for entry in recipe["bodies"]:
        model = registry.get("body_model", entry["model"])
        rig = model.make_body(params=entry["params"])
        pose = load_pose(entry["pose"], frame=entry.get("frame", 0), rig=rig, dirs=registry.pose_dirs)
        if recline is not None:  # the trunk reclined until the back is at the recline set (seatkit.template.seat)
            from seatkit.template.seat import recline_to

            pose, _ = recline_to(lambda p, model=model, rig=rig: pose_canonical(model, rig, p)[0], pose, float(recline) + recline_offset)
        body, frame = pose_canonical(model, rig, pose)
        bodies.append(body)
        frames.append(frame)
    return _placed(recipe, seated_at_height(recipe, bodies, registry)), frames


def _seat_option(recipe: Mapping, registry, key: str):
    """The template's ``seat`` step's option ``key`` as the recipe sets it (None: not set, or no such step)."""
    template = registry.get("template", recipe["template"])
    options = template.step_options("seat", recipe.get("template_params")) if hasattr(template, "step_options") else None
    return None if not options else options.get(key)


def seated_at_height(recipe: Mapping, bodies: list[Body], registry) -> list[Body]:
    """``bodies`` lifted to the seat height the template's ``seat`` step sets, if it sets one (:mod:`seatkit.template.seat`)."""
    height = _seat_option(recipe, registry, "height")
    if height is None:
        return bodies
    from seatkit.template.seat import seat_bodies

    return seat_bodies(bodies, height)


def _placed(recipe: Mapping, bodies: list[Body]) -> list[Body]:
    """``bodies`` at their ``offset`` entries, or side by side (see :func:`place_bodies`); sitters of one seat as they are (the pipeline seats them once their pressure is known: :func:`seatkit.sitters.align_sitters`)."""
    if recipe.get("sitters"):
        return bodies
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


def measure_people(recipe: Mapping, registry) -> list:
    """Each person's survey measurements (:func:`seatkit.body.measure.measure_rig`), None where they cannot be taken."""
    from seatkit.body.measure import measure_rig

    out = []
    for entry in recipe["bodies"]:
        rig = registry.get("body_model", entry["model"]).make_body(params=entry["params"])
        try:
            out.append(measure_rig(rig))
        except (ValueError, IndexError):  # a rig without the legs or arms a measurement reads
            out.append(None)
    return out


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
    contacts = seat_contacts(recipe, bodies, registry)
    return [
        solver.solve(body, **({} if contact is None else {"contact": contact}), lam=p["lambda"], mu=p["mu"], exclude=p.get("exclude"), options=p.get("options") or {})
        for body, contact in zip(bodies, contacts)
    ]


def seat_contacts(recipe: Mapping, bodies, registry) -> list:
    """Per body, the vertices the seat the template's ``seat`` step sets may carry (None: every vertex); a shorter seat leaves the thigh ahead of its front edge out (:func:`seatkit.template.seat.seat_contact`)."""
    depth = _seat_option(recipe, registry, "depth")
    if depth is None:
        return [None] * len(bodies)
    from seatkit.template.seat import seat_contact

    return seat_contact(bodies, float(depth))


def refine(mesh, refiners, bodies, pressures, timer: StageTimer | None = None):
    """``mesh`` after each ``(name, refiner, params)`` in turn, each timed as ``refine:NAME``.

    Each refiner's cage is held to the template's constraints
    (:func:`seatkit.template.checks.check_refined`).
    """
    from seatkit.template.checks import check_refined

    timer = timer or StageTimer()
    for name, refiner, params in refiners:
        with timer.stage(f"refine:{name}"):
            refined = refiner.refine(mesh, bodies, pressures, params=params)
            check_refined(mesh, refined, refiner=getattr(refiner, "component_label", None) or f"refiner {name!r}")
            mesh = refined
    return mesh


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


def fit_baseline(recipe: Mapping, bodies, pressures, registry, segments, timer: StageTimer | None = None) -> Baseline:
    """Fit and evaluate the baseline design of a recipe (default ``flat-patch``).

    The baseline (what Sit & Relax starts from) is fitted to the same bodies,
    asked to support the same body segments as our cage (a baseline template
    that declares a ``segments`` parameter gets them), refined by the
    recipe's ``evaluate.baseline_refiners`` (default ``catmull-clark-fit``,
    the Sit & Relax surface fit), and evaluated the same way
    (:mod:`seatkit.evaluate`). ``timer`` is told each part as it starts
    (``baseline:template``, ``refine:NAME``, ``baseline:surface``,
    ``baseline:evaluate``); its ``progress`` may raise to stop the fit.
    """
    return fit_baseline_with(recipe, bodies, pressures, baseline_components(recipe, registry), segments, timer)


def fit_baseline_with(recipe: Mapping, bodies, pressures, components: tuple, segments, timer: StageTimer | None = None) -> Baseline:
    """:func:`fit_baseline` with its components (:func:`baseline_components`) looked up already."""
    from seatkit.evaluate import evaluate_design
    from seatkit.skeleton import SEGMENTS
    from seatkit.subdivision import limit_surface

    start = time.perf_counter()
    ev, p = recipe["evaluate"], recipe["pressure"]
    template, refiners, solver = components
    params = {"segments": [SEGMENTS[s] for s in segments]} if "segments" in getattr(template, "parameters", ()) else {}
    timer = timer or StageTimer()
    with timer.stage("baseline:template"):
        base = template.fit(bodies, pressures, params=params, seed=recipe["seed"])
    base = refine(base, refiners, bodies, pressures, timer)
    with timer.stage("baseline:surface"):
        surface = limit_surface(base, level=recipe["surface_level"])
    with timer.stage("baseline:evaluate"):
        metrics, fields = evaluate_design(
            bodies, pressures, surface, solver=solver, support_distance=ev["support_distance"], pressure_settings=p, segments=segments
        )
    return Baseline(ev["baseline"], base, surface, metrics, fields, time.perf_counter() - start)


def evaluate_result(
    result: BuildResult,
    registry,
    timer: StageTimer | None = None,
    *,
    baseline: Callable[[], Baseline] | None = None,
    helper=None,
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
    helper : seatkit.workers.Helper, optional
        A helper process (the baseline's, else the export worker) that,
        when it is idle, computes the interface pressure while this process
        evaluates the design; the ``interface pressure`` stage is then the
        wait for it. The figures are the same either way.
    """
    from seatkit.dimensions import person_fit, support_dimensions
    from seatkit.evaluate import design_segments, evaluate_design
    from seatkit.skeleton import SEGMENTS

    timer = timer or StageTimer()
    recipe = result.recipe
    ev = recipe["evaluate"]
    p = recipe["pressure"]
    solver = registry.get("pressure_solver", p["solver"])
    segments = design_segments(result.control_mesh)
    interface = ev.get("interface_pressure", True)
    if interface:
        from seatkit.evaluate import evaluate_interface

        if helper is not None and helper.idle():  # beside the evaluation below (a copy of the bodies and surface there)
            job = helper.submit(functools.partial(evaluate_interface, mu=p.get("mu")), result.bodies, result.surface)

            def interface_now():
                return helper.result(job)

        else:

            def interface_now():
                return evaluate_interface(result.bodies, result.surface, mu=p.get("mu"))

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
    dimensions = support_dimensions(result.bodies, fields)
    metrics = {
        "support_distance_m": ev["support_distance"],
        "supported_segments": [SEGMENTS[s] for s in segments],
        "ours": ours,
        "dimensions": dimensions,
        "person_fit": person_fit(measure_people(recipe, registry), dimensions),  # seat vs person (seatkit.dimensions)
    }
    result.contact_pressures = fields
    if interface:
        with timer.stage("interface pressure"):
            figures, result.interface_pressures = interface_now()
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
