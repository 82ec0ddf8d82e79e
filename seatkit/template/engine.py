"""The YAML template engine: :class:`YamlTemplate` runs a template's steps.

A :class:`YamlTemplate` is a :class:`seatkit.interfaces.SupportTemplate`
built from a validated template file. When it joins a registry it is bound
to the registered steps (:meth:`YamlTemplate.bind`): each ``steps:`` entry
is resolved and checked against the step's option schema, prerequisites
and stage, so that every mistake is a ``file:line`` error before any
geometry. ``fit`` makes one block of faces per
body, runs the declared steps in order (each a registered
:class:`seatkit.interfaces.TemplateStep`), joins the blocks into one grid,
and turns it into a :class:`seatkit.model.ControlMesh` after checking that
it is a connected manifold that crosses neither itself nor any body
(:func:`seatkit.template.checks.check_cage`, numpy and scipy only). A cage
that fails is never returned: :class:`seatkit.errors.UnsupportedPoseError`
names the faces and body parts, with the fit's diagnostics.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import io
import pickle
from collections import namedtuple
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence

import numpy as np

from seatkit.errors import InputError, ParamError, RecipeError, UnsupportedPoseError
from seatkit.model import Body, ControlMesh, PressureField
from seatkit.template.capabilities import HasFallback, HasLastResort, RepairsFaces, WallsInsideHands
from seatkit.template.checks import check_cage, enclosed_parts
from seatkit.template.grid import Block, FaceState, FitState, GridMesh, segment_of_vertex
from seatkit.template.options import check_step_options, did_you_mean
from seatkit.template.schema import FaceSpec, TemplateSpec, read_template, resolve_parameters
from seatkit.template.steps import BUILTIN_STEPS, join_blocks

__all__ = ["YamlTemplate", "load_template", "grid_to_mesh"]

#: Entropy of the fallback RANSAC streams (the same for every seed).
_FALLBACK = 0x5EA7

#: Repairs of the faces the final check names, per start, before the start is refused.
_REPAIR_ROUNDS = 2


def _body_facts(bodies) -> list[tuple]:
    """Per body, what a :class:`Block` derives from the body alone: its vertices' segments and empty caches of segment sets' vertices and centroids (shared by every start's blocks)."""
    return [(segment_of_vertex(b), {}, {}) for b in bodies]


class YamlTemplate:
    """A support template declared in YAML.

    Parameters
    ----------
    spec : TemplateSpec
        The validated document.
    steps : mapping of str to TemplateStep, optional
        The steps its ``steps:`` entries are resolved against. Given, the
        template is bound at once (:meth:`bind`); otherwise it is bound when
        it joins a registry (the registry calls :meth:`bind` with every
        registered step), or, used on its own, to the built-in steps at its
        first fit.
    """

    def __init__(self, spec: TemplateSpec, *, steps: Mapping[str, Any] | None = None):
        self.spec = spec
        self.name = spec.name
        self.description = spec.description or f"template {spec.name} from {spec.source}"
        self._plan: list | None = None
        if steps is not None:
            self._plan = _plan(spec, steps)

    def __repr__(self) -> str:
        return f"YamlTemplate({self.name!r}, {self.spec.source!r})"

    def bind(self, steps: Mapping[str, Any], *, missing_hint: str = "") -> "YamlTemplate":
        """This template with its steps resolved against ``steps`` (a new object).

        Every ``steps:`` entry is looked up and checked: an unknown step, an
        option the step does not declare or a value of the wrong type or range
        (:mod:`seatkit.template.options`), a step whose prerequisite
        (``requires``) is not listed before it, a per-person step after the
        grid was joined: each is a :class:`RecipeError`
        ``file:line: steps[i].key: what was expected``.

        Parameters
        ----------
        steps : mapping of str to TemplateStep
        missing_hint : str
            Added to an unknown-step message (e.g. the disabled plugins).
        """
        bound = YamlTemplate(self.spec)
        bound._plan = _plan(self.spec, steps, missing_hint=missing_hint)
        return bound

    def step_labels(self) -> list[str]:
        """How a recipe names each step (``template_params.steps``): its label, else its name."""
        return [_label(s) for s in self.spec.steps]

    def check_params(self, params: Mapping[str, Any] | None) -> None:
        """Check a recipe's ``template_params`` without fitting.

        Raises
        ------
        ParamError
            With the key path inside ``template_params`` and what was expected.
        """
        self._overrides(params)

    def _overrides(self, params) -> tuple[dict, dict]:
        """(template parameters, {step index: options}) from a recipe's ``template_params``."""
        params = dict(params or {})
        steps = params.pop("steps", None)
        values = resolve_parameters(self.spec, params)
        per_step: dict[int, dict] = {}
        if steps is None:
            return values, per_step
        if not isinstance(steps, Mapping):
            raise ParamError(("steps",), f"expected a mapping of step label or index to options, got {steps!r}")
        plan = self._bound_plan()
        labels = self.step_labels()
        for key, opts in steps.items():
            i = _step_index(key, labels)
            if i is None:
                where = ", ".join(f"{j}: {lab}" for j, lab in enumerate(labels))
                raise ParamError(("steps", key), f"template {self.name!r} has no step {key!r}; its steps are {where}{did_you_mean(key, labels)}")
            if not isinstance(opts, Mapping):
                raise ParamError(("steps", key), f"expected a mapping of option names to values, got {opts!r}")
            step = plan[i][0]

            def fail(path, message, key=key):
                return ParamError(("steps", key) + tuple(path), message)

            merged = {**_given(self.spec.steps[i]), **opts}
            per_step[i] = check_step_options(step.name, step.options, merged, rows=self.spec.rows, columns=self.spec.columns, fail=fail)
        return values, per_step

    def step_options(self, name: str, params: Mapping[str, Any] | None = None) -> dict | None:
        """The options of the step ``name`` (listed once) as a fit with ``params`` runs it: the template's, a recipe's overrides, the defaults; None when the template does not list it once.

        For options applied outside the fit (the ``seat`` step's ``height``
        lifts the bodies when they are placed: :mod:`seatkit.template.seat`).
        """
        names = [entry["step"] for entry in self.spec.steps]
        if names.count(name) != 1:
            return None
        i = names.index(name)
        _, per_step = self._overrides(params)
        return dict(per_step.get(i, self._bound_plan()[i][1]))

    def _bound_plan(self) -> list:
        if self._plan is None:
            self._plan = _plan(self.spec, BUILTIN_STEPS)
        return self._plan

    def fit(
        self,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        *,
        params: Mapping[str, Any] | None = None,
        seed: int = 0,
    ) -> ControlMesh:
        """Fit the template to ``bodies`` (see :class:`seatkit.interfaces.SupportTemplate`): the first of :meth:`fits`."""
        return next(self.fits(bodies, pressures, params=params, seed=seed))

    def fits(
        self,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        *,
        params: Mapping[str, Any] | None = None,
        seed: int = 0,
        last_resort: bool = False,
    ) -> Iterator[ControlMesh]:
        """Every valid cage, one per start that gives one, in the order of the starts.

        A generator: a start runs only when its cage is asked for. The first
        cage is :meth:`fit`'s; the design search asks for the next only when
        the one before is rejected (:mod:`seatkit.search`). When the first cage encloses a hand, the next is the same
        cage with walls inside the hand, if that one is valid and encloses
        less (docs/templates.md, "Walls inside the hands"), built before the
        first cage is offered: the first cage's
        ``meta["fit_attempts"]["encloses_hands"]`` says whether it encloses
        one the steps could wall, and ``walled_next`` whether the walled
        cage follows (the design search refines that one first). Raises the
        first start's refusal when no start gives a valid cage, and a
        refusal of the pose rule at once.

        With ``last_resort`` the same starts run with ``FitState.last_resort``
        set: a step whose options ask for a last-resort change applies it
        (``has_last_resort(options)``: ``fit-planes``' ``last_resort_rows``);
        a template without one yields nothing. Their order differs: each
        stream with every step, then without the optional steps dropped in
        turn, before the next stream; a cage the same as one offered before
        is skipped (:meth:`last_resort_fits`; docs/templates.md,
        "Last-resort cages").
        """
        bodies, pressures = list(bodies), list(pressures)
        lo, hi = self.spec.people
        if not lo <= len(bodies) <= hi:
            want = f"{lo}" if lo == hi else f"{lo} to {hi}"
            raise InputError(f"template {self.name!r} fits {want} people, got {len(bodies)} bodies")
        if len(pressures) != len(bodies):
            raise InputError(f"template {self.name!r}: {len(bodies)} bodies but {len(pressures)} pressure fields")
        for i, (b, p) in enumerate(zip(bodies, pressures)):
            if p.pressure.shape != (len(b.vertices),):
                raise InputError(f"person {i}: pressure has shape {p.pressure.shape}, the body has {len(b.vertices)} vertices")
        p, per_step = self._overrides(params)
        bound = self._bound_plan()
        if last_resort and not any(isinstance(step, HasLastResort) and step.has_last_resort({**o, **per_step.get(i, {})}) for i, (step, o) in enumerate(bound)):
            return
        # Several starts (docs/templates.md, "The starts"): the seed's own
        # RANSAC stream first; when its cage is refused, the same fixed
        # fallback streams whatever the seed, first with every step, then
        # without the last optional step (the chair's armrests), then without
        # the last two (and the backrest below optional_below), and so on. The first valid
        # cage wins, so success does not depend on the seed; the seed only
        # picks among valid designs.
        plan = _starts(p, bound, seed, last_resort)
        first, found = None, False
        offered: list = []
        # a start that drops an optional step which changed nothing in the
        # same stream's refused start is that start again: refused alike
        # without its border, lift and checks (docs/templates.md, "The starts")
        alike = _AlikeStarts(bound)
        # what a block derives from its body alone (the segment of each vertex, the vertices and centroids
        # of segment sets) is the same in every start: made once, shared by the starts' blocks
        facts = _body_facts(bodies)
        for attempt, (k, rng, dropped) in enumerate(plan):
            watch = alike.watch(k, rng, dropped)
            try:
                got = self._attempt(bodies, pressures, p, bound, per_step, rng, seed, dropped, last_resort, watch=watch, facts=facts)
            except UnsupportedPoseError as e:
                if getattr(e, "seed_independent", False):
                    raise
                first = first or e
                alike.refused(watch)
                continue
            if got is None:  # the same fit as a refused start
                alike.refused(watch)
                continue
            mesh, start = got
            if last_resort:
                if any(v.shape == mesh.vertices.shape and np.array_equal(v, mesh.vertices) for v in offered):
                    continue
                offered.append(mesh.vertices)
            stream = "seed" if k == 0 else f"fallback {k}"
            mesh.meta["fit_attempts"] = {"attempt": attempt + 1, "of": len(plan), "stream": stream, "optional_steps_dropped": bool(dropped)}
            if last_resort:
                mesh.meta["fit_attempts"]["last_resort"] = True
            if first is not None:
                mesh.meta["fit_attempts"]["first_refusal"] = str(first)
            walled = None
            if not found:
                # the first cage with walls inside the hands it encloses, if any (docs/templates.md, "Walls
                # inside the hands"): the next cage, before the next start's; the first cage says whether it
                # follows (``walled_next``), and the design search refines it first (seatkit.search)
                found = _enclosed_hands(*start)
                mesh.meta["fit_attempts"]["encloses_hands"] = bool(found)
                walled = _hands_outside(*start, found=found) if found else None
                if walled is not None:
                    walled.meta["fit_attempts"] = {**walled.meta["fit_attempts"], "walls_inside": True}
                mesh.meta["fit_attempts"]["walled_next"] = walled is not None
            yield mesh
            if walled is not None:
                yield walled
            found = True
        if not found:
            first.diagnostics["fit_attempts"] = len(plan)
            raise first

    def walls_against(
        self,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        cage: ControlMesh,
        refused: np.ndarray,
        *,
        params: Mapping[str, Any] | None = None,
        seed: int = 0,
    ) -> ControlMesh | None:
        """The start of ``cage`` again, its side walls inside the hands the refused surface ``refused`` encloses; None when there is none.

        ``cage`` is one of :meth:`fits`' cages, ``refused`` (its vertices'
        count, 3) the control points of the surface a refiner refused for
        it (the surface fit's refit closest to its limit): the design
        search's ``walls-against`` source (:mod:`seatkit.search`). The cage's start is run
        again (the same stream and dropped steps: the same cage), and the
        parts it does not hold (hands, forearms) that lie inside the
        furniture of the refused surface, deeper than ``max_penetration``,
        get walls inside them, beside every row, the backrest's too
        (docs/templates.md, "Walls against a rejected surface"). The walled
        cage passes the template's checks and their repairs, as any cage;
        whether it is better is the acceptance check's to say.
        """
        attempt = int(cage.meta.get("fit_attempts", {}).get("attempt", 0)) - 1
        if attempt < 0 or np.shape(refused) != np.shape(cage.vertices):
            return None
        bodies, pressures = list(bodies), list(pressures)
        p, per_step = self._overrides(params)
        bound = self._bound_plan()
        plan = _starts(p, bound, seed)
        if attempt >= len(plan):
            return None
        _, rng, dropped = plan[attempt]
        refused = np.asarray(refused, dtype=np.float64)
        if not any(isinstance(step, WallsInsideHands) for i, (step, _) in enumerate(bound) if i not in dropped):
            return None  # no step of this start can put walls inside a hand
        found = None
        if not cage.meta["fit_attempts"].get("walls_inside"):
            # the plain start's cage is ``cage`` (its faces, segments and special cases): what the
            # refused surface encloses is known before the start is run again, and nothing enclosed
            # is nothing to wall
            found = enclosed_parts(dataclasses.replace(cage, vertices=refused), bodies, p["max_penetration"])
            if not any(f["vertices"] for f in found):
                return None
        try:
            _, start = self._attempt(bodies, pressures, p, bound, per_step, rng, seed, dropped)
        except UnsupportedPoseError:
            return None
        walled = _walls_against(start, refused, found)
        if walled is not None:
            # built from the plain start: not the walls inside the hands of a walled first cage
            attempts = {k: v for k, v in cage.meta["fit_attempts"].items() if k != "walls_inside"}
            walled.meta["fit_attempts"] = {**attempts, "walls_against_refusal": True}
        return walled

    def last_resort_fits(
        self,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        *,
        params: Mapping[str, Any] | None = None,
        seed: int = 0,
    ) -> Iterator[ControlMesh]:
        """The valid cages of every start with the template's last-resort changes (:meth:`fits` with ``last_resort``).

        The design search's ``last-resort`` source (:mod:`seatkit.search`);
        empty for a template without last-resort changes.
        """
        return self.fits(bodies, pressures, params=params, seed=seed, last_resort=True)

    def _attempt(self, bodies, pressures, p, bound, per_step, rng, seed, dropped=frozenset(), last_resort=False, *, watch=None, facts=None) -> tuple | None:
        """One run of the bound steps and the final check with one random stream.

        Returns the cage and its :class:`_Start` (what
        :func:`_hands_outside` and :func:`_walls_against` build on); None
        when ``watch`` (a :class:`_Watch`) finds, after an optional step,
        that this start is a refused start again. ``facts`` (per body: its
        vertices' segments and the :class:`Block` caches of segment sets'
        vertices and centroids) are shared with the other starts.
        """
        facts = _body_facts(bodies) if facts is None else facts
        blocks = [self._block(i, b, pr, facts[i]) for i, (b, pr) in enumerate(zip(bodies, pressures))]
        state = FitState(self.spec, p, blocks, rng, last_resort=last_resort)
        state.meta["template"] = self.name
        state.meta["seed"] = int(seed)
        state.meta["special_cases"] = []
        for i, (step, options) in enumerate(bound):
            if i in dropped:
                state.meta.setdefault("dropped_steps", []).append(self.spec.steps[i]["step"])
                if isinstance(step, HasFallback):  # the step says what doing without it means (no-backrest)
                    step.fallback(state, options=dict(per_step.get(i, options)))
            else:
                step.run(state, options=dict(per_step.get(i, options)))
            if watch is not None and watch.after(i, state):
                return None
        if state.grid is None:
            state.grid = join_blocks(state)
        state.meta["faces"] = _face_report(state)
        state.meta["supported_segments"] = state.supported_segments()
        repairs = [(step, dict(per_step.get(i, options))) for i, (step, options) in enumerate(bound) if i not in dropped and isinstance(step, RepairsFaces)]
        mesh = _checked_cage(state, bodies, p, repairs)
        fixers = [(step, dict(per_step.get(i, options))) for i, (step, options) in enumerate(bound) if i not in dropped and isinstance(step, WallsInsideHands)]
        return mesh, _Start(state, mesh, bodies, p, fixers, repairs)

    def _block(self, person: int, body: Body, pressure: PressureField, facts: tuple) -> Block:
        faces = {key: FaceState(spec, spec.segments) for key, spec in self.spec.faces.items()}
        segment, members, centroids = facts
        return Block(
            person=person,
            body=body,
            importance=np.asarray(pressure.importance, dtype=np.float64),
            normal_force=np.asarray(pressure.normal_force, dtype=np.float64),
            force=np.asarray(pressure.force, dtype=np.float64),
            segment=segment,
            faces=faces,
            rows=list(range(len(self.spec.rows))),
            n_columns=len(self.spec.columns),
            members=members,
            centroids=centroids,
        )


#: Keys of a ``steps:`` entry that are not options of the step.
STEP_KEYS = ("step", "label")


def _label(entry: Mapping) -> str:
    return str(entry.get("label", entry["step"]))


def _given(entry: Mapping) -> dict:
    return {k: v for k, v in entry.items() if k not in STEP_KEYS}


def _step_index(key, labels: list[str]) -> int | None:
    """Index of the step a recipe names by label (unique), or by index (``3`` or ``"3"``)."""
    if isinstance(key, str) and labels.count(key) == 1:
        return labels.index(key)
    if isinstance(key, bool):
        return None
    try:
        i = int(key)
    except (TypeError, ValueError):
        return None
    return i if 0 <= i < len(labels) and str(i) == str(key).strip() else None


def _plan(spec: TemplateSpec, steps: Mapping[str, Any], *, missing_hint: str = "") -> list:
    """[(step, options with defaults)] of a template's ``steps:``, checked (see :meth:`YamlTemplate.bind`)."""
    plan = []
    seen: list[str] = []
    grid_step = None
    labels = [_label(s) for s in spec.steps]
    for i, entry in enumerate(spec.steps):
        name = entry["step"]
        if name not in steps:
            have = ", ".join(sorted(steps)) or "none"
            raise spec.doc.error(("steps", i, "step"), f"unknown step {name!r}; the registered steps are: {have}{did_you_mean(name, list(steps))}{missing_hint}")
        step = steps[name]
        if "label" in entry and labels.count(str(entry["label"])) > 1:
            raise spec.doc.error(("steps", i, "label"), f"label {entry['label']!r} is given to two steps; a recipe names a step by a unique label")

        def fail(path, message, i=i):
            return spec.doc.error(("steps", i) + tuple(path), message)

        options = check_step_options(name, step.options, entry, rows=spec.rows, columns=spec.columns, fail=fail, ignore=STEP_KEYS)
        for need in step.requires:
            if need not in seen:
                raise spec.doc.error(("steps", i, "step"), f"step {name!r} needs step {need!r} before it; add '- step: {need}' earlier in steps")
        stage = step.stage
        if stage not in ("blocks", "grid"):
            raise spec.doc.error(("steps", i, "step"), f"step {name!r} declares stage {stage!r}; expected 'blocks' or 'grid' (a plugin bug)")
        if stage == "grid":
            grid_step = grid_step or name
        elif grid_step is not None:
            raise spec.doc.error(("steps", i, "step"), f"step {name!r} fits each person's faces, but step {grid_step!r} before it already joined them into one grid; move it before {grid_step!r}")
        seen.append(name)
        plan.append((step, options))
    return plan


def _starts(p: dict, bound: list, seed: int, last_resort: bool = False) -> list:
    """[(stream number, random stream, indices of the steps dropped)] of every start, in order (docs/templates.md, "The starts").

    The seed's own stream (number 0) first; then the fixed fallback streams,
    the same whatever the seed; all of them first with every step, then
    without the last optional step, then without the last two, and so on.
    With ``last_resort`` (the build refines only a few last-resort cages),
    each stream without the optional steps, dropped in turn, before the
    next stream.
    """
    streams = [lambda: np.random.default_rng(seed)] + [lambda k=k: np.random.default_rng([_FALLBACK, k]) for k in range(1, p["fit_attempts"])]
    optional = [i for i, (step, _) in enumerate(bound) if getattr(step, "optional", False)]
    phases = [frozenset(optional[len(optional) - n :]) for n in range(len(optional) + 1)]
    if last_resort:
        order = [(k, dropped) for k in range(len(streams)) for dropped in phases]
    else:
        order = [(k, dropped) for dropped in phases for k in range(len(streams))]
    return [(k, streams[k](), dropped) for k, dropped in order]


class _AlikeStarts:
    """The refused starts of one :meth:`YamlTemplate.fits`, each fit's state after every optional step.

    The starts of one stream differ only in the optional steps they drop
    (:func:`_starts`), and the steps before the first of them run alike. A
    start that drops step ``i`` beside a refused start of its stream that
    ran it (every other step the same) fits the same cage when its state
    after ``i`` is the refused start's: the same faces, grid and taken
    special cases (:func:`_fit_digest`), and the same random stream, or one
    the refused start drew nothing more from. The optional step changed
    nothing there (no armrest for an arm that carries no load, legs too far
    apart to merge): the rest of the start would be the refused start's,
    its border, lift, checks and repairs, and is not run. The design does
    not change; only a refusal is recognised (a valid cage runs whole).
    """

    def __init__(self, bound: list):
        # (a step that repairs the cage after the steps acts when it is not dropped, whatever it changed)
        self.optional = frozenset(i for i, (step, _) in enumerate(bound) if getattr(step, "optional", False) and not isinstance(step, (RepairsFaces, WallsInsideHands)))
        self.runs: dict = {}

    def watch(self, stream: int, rng, dropped) -> "_Watch":
        """What one start records after each optional step, and the refused start it is compared with there."""
        return _Watch(self, stream, rng, frozenset(dropped))

    def refused(self, watch: "_Watch") -> None:
        """``watch``'s start gave no valid cage: keep what it recorded, with its stream's state at the end."""
        watch.end = _stream_state(watch.rng)
        self.runs[(watch.stream, watch.dropped)] = watch


class _Watch:
    """One start's fit states after its optional steps (see :class:`_AlikeStarts`)."""

    def __init__(self, alike: _AlikeStarts, stream: int, rng, dropped: frozenset):
        self.alike, self.stream, self.rng, self.dropped = alike, stream, rng, dropped
        self.seen: dict = {}  # optional step index: (digest, stream state) after it
        self.same_as = None  # (step index, the refused _Watch) this start matched there
        self.end = None

    def after(self, i: int, state: FitState) -> bool:
        """Record the state after step ``i``; True when this start is, from here on, a refused start of its stream."""
        if i not in self.alike.optional:
            return False
        digest, drawn = _fit_digest(state), _stream_state(self.rng)
        self.seen[i] = (digest, drawn)
        if digest is None or i not in self.dropped:
            return False
        run = self.alike.runs.get((self.stream, self.dropped - {i}))
        if run is None or i not in run.seen or run.seen[i][0] != digest:
            return False
        if run.seen[i][1] != drawn and not run.quiet_after(i):
            return False  # another random state, and the rest draws from it
        self.same_as = (i, run)
        return True

    def quiet_after(self, i: int) -> bool:
        """This start drew nothing from its stream after step ``i`` (to its refusal)."""
        if i not in self.seen:
            return False
        if self.same_as is None:
            return self.end is not None and self.seen[i][1] == self.end
        j, run = self.same_as
        return i <= j and self.seen[i][1] == self.seen[j][1] and run.quiet_after(j)


def _stream_state(rng) -> object:
    """The random stream's state (equal states: nothing drawn in between)."""
    return copy.deepcopy(rng.bit_generator.state)


class _Pickler(pickle.Pickler):
    """Pickles a fit's state with the bodies and the template's face specs by identity (every start shares them)."""

    def persistent_id(self, obj):
        if isinstance(obj, (Body, FaceSpec, TemplateSpec)):
            return (type(obj).__name__, id(obj))
        return None


def _fit_digest(state: FitState) -> bytes | None:
    """A digest of what a fit's later steps read: the blocks' faces, the grid, the border's callbacks and the special cases taken; None when it cannot be taken.

    ``meta`` is the fit's report, and its records of special cases not
    taken (and of dropped steps) leave the cage as it is; the random stream
    is compared on its own (:class:`_Watch`).
    """
    taken = [case for case in state.meta.get("special_cases", []) if case.get("taken")]
    # a block's body, importance and forces are the fit's input, the same in every start, and its
    # members and centroids caches of them: what the steps change are its faces, rows, estimates and cases
    blocks = [(b.person, b.body, b.faces, b.rows, b.n_columns, b.estimates, b.cases) for b in state.blocks]
    buf = io.BytesIO()
    try:
        _Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL).dump((blocks, state.grid, state.rebuild_border, state.rebuild_walls, state.keep_border, state.last_resort, taken))
    except (pickle.PicklingError, TypeError, AttributeError):
        return None  # a step keeps something that cannot be pickled: no start is recognised
    return hashlib.sha256(buf.getvalue()).digest()


#: One start's fit once its cage passed the checks: what a second design of the same start builds on.
_Start = namedtuple("_Start", "state mesh bodies p fixers repairs")


def _checked_cage(state: FitState, bodies, p: dict, repairs: list) -> ControlMesh:
    """The fit's cage once it passes :func:`check_cage`; the faces the check names repaired first, up to ``_REPAIR_ROUNDS`` times.

    Raises the check's last refusal when no repair helps (docs/templates.md,
    "Repairing the faces the check names").
    """
    for round_ in range(_REPAIR_ROUNDS + 1):
        mesh = grid_to_mesh(state.grid, meta=state.meta)
        try:
            check_cage(mesh, bodies, tolerance=p["max_penetration"] + 1e-3)
            return mesh
        except UnsupportedPoseError as e:
            # repair the faces the check names
            faces = e.diagnostics.get("crossing_faces")
            if faces is None and e.diagnostics.get("self_intersections"):
                # a fold: the faces of every intersecting pair (the border's repair lowers a ring folded over a hanging hand)
                faces = sorted({int(f) for pair in e.diagnostics["self_intersections"] for f in pair})
            if faces is None or round_ == _REPAIR_ROUNDS or not any(step.repair(state, faces, options=o) for step, o in repairs):
                raise
    raise AssertionError("unreachable")


def _enclosed_hands(state: FitState, mesh: ControlMesh, bodies, p: dict, fixers: list, repairs: list) -> list:
    """What the cage ``mesh`` encloses of the parts it does not hold (:func:`seatkit.template.checks.enclosed_parts`), when a step could put walls inside it; else []."""
    found = enclosed_parts(mesh, bodies, p["max_penetration"] + 1e-3) if fixers else []
    return found if any(f["vertices"] for f in found) else []


def _hands_outside(state: FitState, mesh: ControlMesh, bodies, p: dict, fixers: list, repairs: list, *, found: list) -> ControlMesh | None:
    """The cage ``mesh`` that passed the checks, with walls inside the hands it encloses (``found``, :func:`_enclosed_hands`); None when it gives no better cage.

    The body parts the cage does not hold (a hand, a forearm) that lie more
    than ``max_penetration`` + 1 mm inside the furniture its limit surface
    closes with the floor (:func:`seatkit.template.checks.enclosed_parts`)
    are handed to the steps that can put walls inside them
    (``repair_enclosure``: the clearance step's). Their cage goes through the
    checks and their repairs (:func:`_checked_cage`) and is returned when it
    passes and encloses less (its deepest enclosed vertex shallower), with
    ``meta["enclosed"]`` saying what was found before and after. ``mesh``
    itself is left as it is (the state works on a copy of its ``meta``).
    """
    tolerance = p["max_penetration"] + 1e-3
    state.meta = copy.deepcopy(mesh.meta)
    before = max(f["depth_m"] for f in found)
    if not any(step.repair_enclosure(state, [f["vertices"] for f in found], options=o) for step, o in fixers):
        return None
    try:
        walled = _checked_cage(state, bodies, p, repairs)
    except UnsupportedPoseError:
        return None
    after = enclosed_parts(walled, bodies, tolerance)
    depth = max(f["depth_m"] for f in after)
    if depth >= before:
        return None
    walled.meta["enclosed"] = {"before": {"depth_m": before, "parts": [f["parts"] for f in found]}, "after": {"depth_m": depth, "parts": [f["parts"] for f in after]}}
    return walled


def _walls_against(start: _Start, refused: np.ndarray, found: list | None = None) -> ControlMesh | None:
    """The cage of ``start`` with walls inside the hands that the refused surface ``refused`` encloses; None when it gives no valid cage.

    ``refused`` are control points of the cage's topology, the surface a
    refiner refused (the surface fit's refit closest to its limit). The
    body parts the cage does not hold that lie more than ``max_penetration``
    inside the furniture that surface closes with the floor
    (:func:`seatkit.template.checks.enclosed_parts`) are handed to the
    steps' ``repair_enclosure`` with walls allowed beside every row, the
    backrest's too; the cage goes through the checks and their repairs
    (:func:`_checked_cage`). Unlike :func:`_hands_outside`, the walled cage
    need not enclose less than the template's cage: it answers a surface
    the refiners refused, and they judge it. ``meta["enclosed"]`` says
    what the refused surface enclosed and what the walled cage's limit
    surface encloses. ``found`` is what the refused surface encloses when
    it was measured already, on a cage with ``mesh``'s faces, segments and
    special cases (:meth:`YamlTemplate.walls_against`).
    """
    state, mesh, bodies, p, fixers, repairs = start
    if found is None:
        found = enclosed_parts(dataclasses.replace(mesh, vertices=refused), bodies, p["max_penetration"])
    if not any(f["vertices"] for f in found) or not fixers:
        return None
    state.meta = copy.deepcopy(mesh.meta)
    if not any(step.repair_enclosure(state, [f["vertices"] for f in found], options=o, every_row=True) for step, o in fixers):
        return None
    try:
        walled = _checked_cage(state, bodies, p, repairs)
    except UnsupportedPoseError:
        return None
    after = enclosed_parts(walled, bodies, p["max_penetration"] + 1e-3)
    walled.meta["enclosed"] = {
        "refused": {"depth_m": max(f["depth_m"] for f in found), "parts": [f["parts"] for f in found]},
        "after": {"depth_m": max(f["depth_m"] for f in after), "parts": [f["parts"] for f in after]},
    }
    return walled


def _face_report(state: FitState) -> list:
    out = []
    for block in state.blocks:
        for (r, c), f in sorted(block.faces.items()):
            if r in block.rows and f.plane is not None:
                out.append({"person": block.person, "face": state.face_name(f), "segments": state.segment_names(f.segments), "supported_vertices": int(len(f.supported)), **{k: v for k, v in f.info.items() if k != "rejected"}, "rejected": dict(f.info.get("rejected", {}))})
    return out


def grid_to_mesh(grid: GridMesh, *, meta: dict) -> ControlMesh:
    """A :class:`ControlMesh` from a structured grid.

    Face (i, j) is ``(i, j), (i, j+1), (i+1, j+1), (i+1, j)``: counter-
    clockwise seen from the side ``d_side x d_up`` points to, the body.
    A vertex's weight is the mean importance of the faces around it plus
    0.05, so that the optimize refiner keeps supporting vertices in place
    and lets border vertices move.
    """
    R, C = grid.shape
    ids = np.arange((R + 1) * (C + 1)).reshape(R + 1, C + 1)
    quads = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], axis=-1).reshape(-1, 4)
    fw = grid.face_weight.ravel()
    acc = np.zeros((R + 1) * (C + 1))
    cnt = np.zeros_like(acc)
    for i in range(4):
        np.add.at(acc, quads[:, i], fw)
        np.add.at(cnt, quads[:, i], 1.0)
    weights = acc / np.maximum(cnt, 1.0) + 0.05
    ground = grid.ground.ravel().copy()
    fixed = ground.copy() if grid.fixed is None else ground | np.asarray(grid.fixed, bool).ravel()
    return ControlMesh(
        vertices=grid.vertices.reshape(-1, 3).copy(),
        faces=quads.astype(np.int64),
        face_segments=grid.segment.ravel().astype(np.int64),
        face_person=grid.person.ravel().astype(np.int64),
        face_labels=tuple(str(x) for x in grid.label.ravel()),
        plane_points=grid.plane_point.reshape(-1, 3).copy(),
        plane_normals=grid.plane_normal.reshape(-1, 3).copy(),
        vertex_weights=weights,
        fixed=fixed,
        ground=ground,
        meta=meta,
    )


def load_template(path: str | Path | None = None, *, text: str | None = None, source: str = "<template>", steps: Mapping[str, Any] | None = None) -> YamlTemplate:
    """Load a YAML template file (or YAML ``text``) as a :class:`YamlTemplate`.

    The document is read and checked (:func:`seatkit.template.schema.read_template`);
    its steps are resolved and checked against ``steps`` when given, else when the
    template joins a registry (:meth:`YamlTemplate.bind`).

    Raises
    ------
    RecipeError
        ``file:line: key.path: problem`` when the template is invalid.
    """
    if path is None and text is None:
        raise RecipeError("load_template needs a path or text")
    spec = read_template(path if path is not None else source, text=text)
    if steps is None:
        # early feedback: the entries of built-in steps are checked now, the
        # others when the template joins a registry
        for i, entry in enumerate(spec.steps):
            step = BUILTIN_STEPS.get(entry["step"])
            if step is not None:
                check_step_options(step.name, step.options, entry, rows=spec.rows, columns=spec.columns, fail=lambda path, m, i=i: spec.doc.error(("steps", i) + tuple(path), m), ignore=STEP_KEYS)
    return YamlTemplate(spec, steps=steps)
