"""The design search: which of the cages a build can make becomes the design.

A template offers cages; the refiners fit each to the body; the acceptance
check judges the fitted cage. This module is that search, whole:

- a :class:`Candidate` is a cage, where it came from (its :class:`Origin`)
  and the template start it belongs to;
- the sources of candidates are declared once, in order, each with one
  budget counted in candidates (:data:`SOURCES`); a source offers nothing
  the template cannot make (:class:`~seatkit.interfaces.OffersStarts`,
  :class:`~seatkit.interfaces.OffersWallsAgainst`,
  :class:`~seatkit.interfaces.OffersLastResort`, checked once in
  :func:`bind`);
- :func:`judge` returns a :class:`Verdict` (accepted, or the reason)
  instead of raising: a fitted surface deeper than the surface fit's
  ``surface_limit`` (5 mm) into the body, or a body vertex deeper inside
  the furniture, is a rejection with its depths, as is a refiner's
  :class:`~seatkit.errors.SolverError` (its message is the reason);
- :func:`search` is the loop: candidates are refined and judged in the
  sources' order until one is accepted or every budget is spent, a repair
  (the push-out) asked right after each rejection;
- :class:`Outcome` is what it found, and :meth:`Outcome.report` the
  ``search`` section of report.json: the winner's origin and every
  rejected candidate's reason.

Budgets are counts, never seconds, so the same recipe and seed take the
same route on every machine, and the slowest build is bounded by the sum
of the budgets (docs/templates.md, "The design search").
"""

from __future__ import annotations

import collections
import contextlib
import enum
from dataclasses import dataclass, field, replace
from typing import Callable, Iterator, Sequence

import numpy as np

from seatkit.errors import SolverError, UnsupportedPoseError
from seatkit.interfaces import OffersLastResort, OffersStarts, OffersWallsAgainst
from seatkit.model import ControlMesh

__all__ = ["Candidate", "Origin", "Outcome", "Source", "SOURCES", "Tried", "Verdict", "bind", "judge", "search", "template_cages"]


class Origin(enum.Enum):
    """Where a candidate cage came from."""

    START = "start"  #: one of the template's starts, in its order (``fits``)
    PUSHED_OUT = "pushed-out"  #: a rejected design with its spots over the limit pushed away from the body
    WALLS_INSIDE = "walls-inside"  #: the template's first cage with walls inside the hands it encloses (refined before that cage)
    WALLS_AGAINST = "walls-against"  #: a rejected design's start again, walls inside the hands its surface encloses
    LAST_RESORT = "last-resort"  #: the template's last-resort cages


@dataclass(frozen=True)
class Candidate:
    """A cage the search may make the design: its ``origin`` and the template ``start`` it belongs to (1-based, 0 unknown).

    ``refined`` is the design the source made already from ``cage`` (a
    pushed-out design: ``cage`` is the template's cage it was refined
    from), None when the refiners are still to run.
    """

    cage: ControlMesh
    origin: Origin
    start: int
    refined: ControlMesh | None = None


@dataclass(frozen=True)
class Verdict:
    """The acceptance check's answer: ``accepted``, else the ``reason``; ``depth_m`` the deepest of the two 5 mm figures (nan unmeasured)."""

    accepted: bool
    reason: str = ""
    depth_m: float = float("nan")


@dataclass(frozen=True)
class Tried:
    """One candidate the search refined: its refined cage (None when a refiner refused it) and the verdict."""

    candidate: Candidate
    refined: ControlMesh | None
    verdict: Verdict


@dataclass(frozen=True)
class Source:
    """A source of candidates: its origin, its budget (candidates refined, at most) and ``offer(tried)``, an iterator of candidates."""

    origin: Origin
    budget: int
    offer: Callable[[Sequence[Tried]], Iterator[Candidate]]


#: The sources, in order, with their budgets (candidates refined, at most).
#: The whole search refines at most their sum; docs/templates.md, "The
#: design search", gives what each earns on the drawn-pose benchmark.
BUDGETS: dict[Origin, int] = {
    Origin.START: 3,
    Origin.PUSHED_OUT: 1,  # a push-out is offered only within the limit, which the check accepts: one is the most refined
    Origin.WALLS_INSIDE: 1,
    Origin.WALLS_AGAINST: 2,
    Origin.LAST_RESORT: 2,
}


@dataclass
class Outcome:
    """What :func:`search` found: every candidate ``tried``, in order, and the index of the ``winner`` (None: every one rejected)."""

    tried: list[Tried] = field(default_factory=list)
    winner: int | None = None

    def design(self) -> tuple[ControlMesh, ControlMesh]:
        """``(cage, refined)`` of the winner, each with the ``search`` report in its meta; raises the first rejection's reason when there is none."""
        if self.winner is None:
            raise SolverError(self.refusal())
        won = self.tried[self.winner]
        report = self.report()
        cage = replace(won.candidate.cage, meta={**won.candidate.cage.meta, "search": report})
        return cage, replace(won.refined, meta={**won.refined.meta, "search": report})

    def refusal(self) -> str:
        """One line saying why no candidate became the design: the first one's reason, and how many were tried."""
        if not self.tried:
            return "the design search had no candidate"
        kinds = ", ".join(f"{n} {o}" for o, n in collections.Counter(t.candidate.origin.value for t in self.tried).items())
        return f"no design within the limits: {self.tried[0].verdict.reason} (the first cage; {len(self.tried)} candidates tried: {kinds}); the design is refused rather than returned sinking into the person"

    def report(self) -> dict:
        """The ``search`` section of report.json: the winner's origin and start, and every candidate's verdict, in order."""
        rows = [
            {"origin": t.candidate.origin.value, "start": t.candidate.start, "accepted": t.verdict.accepted, "reason": t.verdict.reason, "depth_m": t.verdict.depth_m, "over_limit_fits_m": _fit_depths(t.refined)}
            for t in self.tried
        ]
        won = self.tried[self.winner].candidate if self.winner is not None else None
        return {
            "winner": None if won is None else {"origin": won.origin.value, "start": won.start, "candidate": self.winner + 1},
            "candidates": rows,
            "budgets": {o.value: n for o, n in BUDGETS.items()},
        }


def judge(refined: ControlMesh, bodies, *, measured: bool = False) -> Verdict:
    """The acceptance check of a refined cage: within the surface fit's ``surface_limit``, or the reason it is not.

    The limit is the ``catmull-clark-fit`` refiner's ``surface_limit`` (5 mm
    by default, 0 turns the check off) and the depths are the two the
    evaluation reports: how deep the limit surface reaches into a body,
    and how deep a body vertex lies inside the furniture the surface closes
    with the floor. With ``measured`` (the surface fit was the last refiner,
    or the candidate's source measured it) they are the fit's own
    measurement of this cage (``final_depth``), else measured here. A
    design the surface fit did not make is accepted as it is.
    """
    from seatkit.refine.ccfit import final_depths

    report = refined.meta.get("catmull-clark-fit")
    if not report:
        return Verdict(True)
    limit = float(report["params"]["surface_limit"])
    if limit <= 0:
        return Verdict(True)
    depths = report.get("final_depth") if measured else None
    depths = depths or final_depths(refined, bodies, report["params"]["level"])
    deepest = max(depths.values())
    if deepest <= limit:
        return Verdict(True, depth_m=deepest)
    return Verdict(
        False,
        f"the fitted surface reaches {depths['surface_in_body'] * 1000:.1f} mm into the body and a body vertex lies "
        f"{depths['body_in_surface'] * 1000:.1f} mm inside the furniture, above the {limit * 1000:.1f} mm limit (surface_limit)",
        deepest,
    )


def template_cages(template, bodies, pressures, *, params, seed) -> Iterator[ControlMesh]:
    """The template's valid cages in its order of preference: its ``fits`` (:class:`~seatkit.interfaces.OffersStarts`), else its one ``fit``. Lazy."""
    if isinstance(template, OffersStarts):
        yield from template.fits(bodies, pressures, params=params, seed=seed)
    else:
        yield template.fit(bodies, pressures, params=params, seed=seed)


def bind(template, bodies, pressures, *, params, seed, first: Iterator[ControlMesh]) -> tuple[Source, ...]:
    """The declared sources for one build, in order, with what this template can offer.

    ``first`` is :func:`template_cages` with its first cage taken already
    (the build fits it before the search, to start the baseline beside it),
    put back in front.
    """
    walls = isinstance(template, OffersWallsAgainst)
    last = isinstance(template, OffersLastResort)
    cages = _until_refused(first)
    plain: list[ControlMesh] = []  # a first cage that encloses a hand, offered after its walled cage: the walls-inside source's

    def starts(tried):
        while True:
            cage = next(cages, None)
            if cage is None:
                return
            if not tried and cage.meta.get("fit_attempts", {}).get("walled_next"):
                # the template's next cage is this first one with walls inside the hands it encloses
                # (OffersStarts.fits): the walled cage first, the first cage itself in the walls-inside source's turn
                walled = next(cages, None)
                if walled is not None:
                    plain.append(cage)
                    cage = walled
            yield Candidate(cage, Origin.WALLS_INSIDE if _walled(cage) else Origin.START, _start(cage))

    def walls_inside(tried):
        # the first cage of a pair whose walled cage came first (starts): in the first round, once that one is rejected
        while not tried:
            yield None  # the first candidate is not refined yet (the search stops once one is accepted)
        if plain:
            cage = plain.pop()
            yield Candidate(cage, Origin.START, _start(cage))

    def pushed_out(tried):
        from seatkit.refine.ccfit import push_out

        done: set[int] = set()
        while True:
            # the rejected design closest to the limit that is not pushed out yet
            over = sorted((t.verdict.depth_m, i) for i, t in enumerate(tried) if i not in done and t.refined is not None and not t.verdict.accepted and t.candidate.origin in _PUSHABLE)
            found = None
            for _, i in over:
                done.add(i)
                found = push_out(tried[i].refined, bodies)
                if found is not None:
                    yield Candidate(tried[i].candidate.cage, Origin.PUSHED_OUT, tried[i].candidate.start, refined=found)
                    break
            if found is None:
                yield None  # nothing to push out now; a later rejection may give something

    def walls_against(tried):
        done: set[int] = set()
        while walls:
            cage = None
            for i, t in enumerate(tried):
                if i in done or t.refined is None or t.verdict.accepted or t.candidate.origin is not Origin.START:
                    continue
                done.add(i)
                try:
                    cage = template.walls_against(bodies, pressures, t.candidate.cage, t.refined.vertices, params=params, seed=seed)
                except UnsupportedPoseError:
                    cage = None  # the template refuses the start again: nothing to offer
                if cage is not None:
                    yield Candidate(cage, Origin.WALLS_AGAINST, t.candidate.start)
                    break
            if cage is None:
                yield None  # no rejected start to answer now

    def last_resort(tried):
        if last:
            for cage in _until_refused(template.last_resort_fits(bodies, pressures, params=params, seed=seed)):
                yield Candidate(cage, Origin.LAST_RESORT, _start(cage))

    offers = {Origin.START: starts, Origin.PUSHED_OUT: pushed_out, Origin.WALLS_INSIDE: walls_inside, Origin.WALLS_AGAINST: walls_against, Origin.LAST_RESORT: last_resort}
    return tuple(Source(origin, budget, offers[origin]) for origin, budget in BUDGETS.items())


SOURCES = tuple(BUDGETS)

#: The sources asked right after each rejected candidate, not in their turn: repairs of a rejected design, which run no refiner.
_REPAIRS = (Origin.PUSHED_OUT,)
#: The template's own cages: its starts and its first cage with walls inside the hands it encloses.
_STARTS = (Origin.START, Origin.WALLS_INSIDE)
#: The rejected designs a push-out answers: the template's own cages and those walled against a rejected surface, not a rescue of a rescue.
_PUSHABLE = (*_STARTS, Origin.WALLS_AGAINST)


def search(sources: Sequence[Source], refine: Callable[[ControlMesh], ControlMesh], bodies, *, fit_last: bool = True, stage=None) -> Outcome:
    """Refine and judge candidates in rounds, one from each source in order, each source up to its budget, until one is accepted.

    A round asks every source with budget left for one candidate; a source
    may have none this round (``None``: nothing to derive from yet) or be
    spent (its iterator ends). A repair source (the push-out) is not asked
    in its turn but right after each rejected candidate, until it offers
    nothing or one of its designs is rejected too. The search ends at the
    first accepted candidate, or after a round that refined nothing.

    ``refine`` runs the build's refiners on a cage (raising
    :class:`~seatkit.errors.SolverError` when one refuses it: a rejection
    with its message as the reason); ``fit_last`` says the surface fit is
    its last refiner (:func:`judge` then reads the fit's own measurement).
    A candidate the source made refined already (a pushed-out design,
    measured by its repair) is only judged; a cage refined already (a
    walled start and the same start walled against its rejection can be
    one cage) is skipped, uncounted: the refiners would give it the same
    verdict. Every candidate's verdict
    is kept, in order, in the :class:`Outcome`. ``stage(name)`` (a
    :meth:`seatkit.stages.StageTimer.stage`) times the sources' work.
    """
    stage = stage or (lambda name: contextlib.nullcontext())
    outcome = Outcome()
    offered = [source.offer(outcome.tried) for source in sources]
    left = [source.budget for source in sources]
    repairs = [k for k, source in enumerate(sources) if source.origin in _REPAIRS]

    def ask(k) -> bool | None:
        """One candidate of source ``k`` refined and judged: its verdict (True: accepted), None when it had none."""
        with stage("refine:push-out" if sources[k].origin is Origin.PUSHED_OUT else "template"):
            candidate = next(offered[k], False)
        if candidate is False:
            left[k] = 0  # the source is spent
        if not candidate:
            return None  # nothing from this source now
        if candidate.refined is None and any(_same_cage(candidate.cage, t.candidate.cage) for t in outcome.tried if t.candidate.refined is None):
            return None  # a cage refined already (two sources derive it alike): its verdict would be the same
        left[k] -= 1
        refined, verdict = candidate.refined, None
        if refined is None:
            try:
                refined = refine(candidate.cage)
            except SolverError as e:
                refined, verdict = None, Verdict(False, str(e))
        verdict = verdict or judge(refined, bodies, measured=fit_last or candidate.refined is not None)
        outcome.tried.append(Tried(candidate, refined, verdict))
        if verdict.accepted:
            outcome.winner = len(outcome.tried) - 1
        return verdict.accepted

    while True:
        progressed = False
        for k in range(len(sources)):  # one round: one candidate of each source, in order
            if left[k] <= 0 or k in repairs:
                continue
            verdict = ask(k)
            progressed = progressed or verdict is not None
            if verdict:
                return outcome
            # a repair answers each rejection at once, before the next source is asked
            for r in repairs:
                while verdict is False and left[r] > 0:
                    verdict = ask(r)
                    if verdict:
                        return outcome
        if not progressed:
            return outcome


def _fit_depths(refined: ControlMesh | None) -> list[float]:
    """The deepest of the two 5 mm figures after each fit of the surface fit that was over its limit, in order (empty: none was)."""
    report = (refined.meta.get("catmull-clark-fit") if refined is not None else None) or {}
    return [max(r["surface_in_body"], r["body_in_surface"]) for r in report.get("repair_rounds", ())]


def _same_cage(a: ControlMesh, b: ControlMesh) -> bool:
    """``a`` and ``b`` are the same cage: the same faces and control points, bit for bit (the refiners are deterministic)."""
    return a.vertices.shape == b.vertices.shape and np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


def _walled(cage: ControlMesh) -> bool:
    """``cage`` is a template start's cage with walls inside the hands that start's cage enclosed (the YAML engine's ``fit_attempts.walls_inside``)."""
    return bool(cage.meta.get("fit_attempts", {}).get("walls_inside"))


def _start(cage: ControlMesh) -> int:
    """The template start a cage came from (the YAML engine's ``fit_attempts.attempt``), 0 when it does not say."""
    return int(cage.meta.get("fit_attempts", {}).get("attempt", 0))


def _until_refused(cages: Iterator[ControlMesh]) -> Iterator[ControlMesh]:
    """``cages`` until the template refuses the rest (an :class:`~seatkit.errors.UnsupportedPoseError` ends them)."""
    try:
        yield from cages
    except UnsupportedPoseError:
        return
