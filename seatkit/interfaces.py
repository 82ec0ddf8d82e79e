"""The component interfaces plugins implement.

A component is any object with a ``name`` (its registered name, used in
recipes and on the command line), a one-line ``description``, and the method
of its kind. Plugins return them from the registration hooks in
:mod:`seatkit.hookspecs`. They are :class:`typing.Protocol` classes, so a
plugin needs no base class; :func:`isinstance` checks the shape at
registration time (``runtime_checkable``).

Every method takes keyword-only options and returns new objects; components
hold no per-build state, so one instance serves many builds and threads.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator, Mapping, Protocol, Sequence, runtime_checkable

import numpy as np

from seatkit.model import Body, BuildResult, ControlMesh, Pose, PressureField, RiggedBody


@runtime_checkable
class BodyModel(Protocol):
    """Makes a rigged body and poses it.

    ``name`` is e.g. ``default-male``, ``default-female``, ``file``, ``anny``.
    """

    name: str
    description: str

    def make_body(self, *, params: Mapping[str, Any]) -> RiggedBody:
        """Build the rest-pose rigged body from model parameters.

        Parameters
        ----------
        params : mapping
            Model parameters from the recipe (``mass`` in kg for every model;
            ``path`` for ``file``; ``height``, ``weight``, ``age``... for
            parametric models). Unknown keys raise :class:`RecipeError`.

        Returns
        -------
        RiggedBody
        """
        ...

    def pose(self, rig: RiggedBody, pose: Pose, *, ground: bool = True) -> Body:
        """Pose ``rig`` by linear blend skinning.

        Parameters
        ----------
        rig : RiggedBody
        pose : Pose
        ground : bool
            Move the body vertically so that its lowest vertex is at y = 0.

        Returns
        -------
        Body
        """
        ...


@runtime_checkable
class PressureSolver(Protocol):
    """Computes the reaction of a support on a body (paper Section 4)."""

    name: str
    description: str

    def solve(
        self,
        body: Body,
        *,
        contact: np.ndarray | None = None,
        lam: float | None = None,
        mu: float | None = None,
        exclude: Sequence[str] | None = None,
        options: Mapping[str, Any] | None = None,
    ) -> PressureField:
        """Solve for the reaction forces holding ``body`` in equilibrium.

        Parameters
        ----------
        body : Body
        contact : (n,) bool, optional
            Vertices that may carry a reaction; default every vertex (the
            paper's "supported everywhere").
        lam : float, optional
            Moment/pressure balance; ``inf`` treats the body as rigid.
        mu : float, optional
            Friction coefficient.
        exclude : sequence of str, optional
            Named regions given zero user weight (nu); default the solver's own.
        options : mapping, optional
            Solver-specific settings (backend name, tolerances).

        Returns
        -------
        PressureField

        Raises
        ------
        InfeasibleSupportError
            When the contact set cannot hold the body.
        """
        ...


@runtime_checkable
class SupportTemplate(Protocol):
    """Fits a furniture cage to one or more posed bodies (paper Section 5)."""

    name: str
    description: str

    def fit(
        self,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        *,
        params: Mapping[str, Any] | None = None,
        seed: int = 0,
    ) -> ControlMesh:
        """Fit the template.

        Parameters
        ----------
        bodies : sequence of Body
            The posed bodies in seat order (one for a chair).
        pressures : sequence of PressureField
            Each body's importance map.
        params : mapping, optional
            Overrides of the template's declared parameters.
        seed : int
            Seed of every random choice (RANSAC); same seed, same cage.

        Returns
        -------
        ControlMesh

        Raises
        ------
        UnsupportedPoseError
            When a pose cannot be supported by this topology.

        Notes
        -----
        A template may offer more than one cage, and more kinds of cage, by
        having the methods of :class:`OffersStarts`, :class:`OffersWallsAgainst`
        and :class:`OffersLastResort` (the YAML engine has all three); the
        design search (:mod:`seatkit.search`) checks which once, when it is
        given the template, and asks for them in its declared order.
        """
        ...

    def bind(self, steps: Mapping[str, "TemplateStep"]) -> "SupportTemplate":
        """The template as it joins a registry, its steps resolved.

        Called by the registry once every plugin's components are known, with
        every registered :class:`TemplateStep` by name; returns the object to
        register (``self`` for a template that uses no steps). Raises
        :class:`~seatkit.errors.RecipeError` (file, line, key path) for a step
        it cannot use: the template is then left out of the registry and the
        problem is reported.
        """
        ...

    def check_params(self, params: Mapping[str, Any] | None) -> None:
        """Check a recipe's ``template_params`` before any geometry.

        Raises
        ------
        ParamError
            With the key path inside ``template_params``; the recipe checker
            adds the recipe's file and line.
        """
        ...


@runtime_checkable
class Refiner(Protocol):
    """Improves a cage after the template (paper Section 5.3, surface fit).

    It may declare ``options`` (name -> :class:`seatkit.options.Option`):
    a recipe's ``params`` for it are checked against them before any
    geometry (without ``options`` it takes none). Its cage must keep the
    template's constraints (:func:`seatkit.template.checks.check_refined`).
    """

    name: str
    description: str

    def refine(
        self,
        mesh: ControlMesh,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        *,
        params: Mapping[str, Any] | None = None,
    ) -> ControlMesh:
        """Return the refined cage (same topology)."""
        ...


@runtime_checkable
class Exporter(Protocol):
    """Writes part of a build result to files.

    ``prepare_ahead`` says whether :meth:`prepare` is worth running ahead:
    a build runs such exporters in its export worker process, which calls
    ``prepare()`` while the design is computed (:mod:`seatkit.workers`);
    ``export`` then gets a pickled copy of the result (exporters must
    pickle). Other exporters run in the build's process, and their
    ``prepare()`` is called just before ``export``. An exporter that declares
    ``options`` (name -> :class:`seatkit.options.Option`) is called
    ``export(result, directory, options=...)`` with a recipe's ``params``
    for it, checked before any geometry, and its defaults. An exporter may
    also say ``runs_apart = True`` (optional, default false): it costs much
    to run but imports nothing big (the report's pictures), so a build
    with an idle helper process (the baseline's, its work done) runs it
    there, on a pickled copy of the result, beside the other exporters;
    one whose work divides declares ``parts`` (a count),
    ``export_part(result, directory, part)`` and optionally
    ``join_parts(list of each part's files)``, and the build runs the parts
    in its idle processes in turn. An exporter with work that needs only
    the bodies and their importance pressure (the report's ``pressure.png``)
    may declare ``export_early(result)``: a build with helper processes
    calls it in one of them as soon as those pressures are solved, on a
    result that holds only the recipe, the bodies and the pressures, and
    passes what it returned (pickled) to ``export`` and ``export_part`` as
    the keyword ``early`` (None when it did not run or failed). The
    exporter must use it only where it still fits the result it exports
    (a seat height set, or sitters, move the bodies later). An exporter
    whose ``export`` reads only the design may say ``design_only = True``
    (optional, default false), and one with parts may list the parts that
    do in ``design_parts``: the design is the recipe, the bodies and their
    importance pressure, both cages, the surface and the frames; not the
    evaluation (``metrics``, ``contact_pressures``,
    ``interface_pressures``, ``baseline``, ``timings``, ``structure``,
    ``shell_thickness_m``: None or empty there). One that reads the
    baseline's design too (``result.baseline``: its cage and surface)
    says ``reads_baseline = True``. A build with helper processes runs
    that work in its export worker as soon as the design is made (and,
    for ``reads_baseline``, the baseline fitted), on a pickled copy,
    while it evaluates the design; the files must be those ``export``
    writes from the whole result.
    """

    name: str
    description: str
    prepare_ahead: bool

    def prepare(self) -> None:
        """Get ready to export (import a big library); write nothing. May do nothing."""
        ...

    def export(self, result: BuildResult, directory: Path) -> dict[str, Path]:
        """Write files into ``directory`` and return them by role.

        Files must be written atomically (see :func:`seatkit.io.atomic_write`).
        """
        ...


@runtime_checkable
class TemplateStep(Protocol):
    """One named fitting step a YAML template can list under ``steps``.

    Attributes a step declares (see "Writing a template step" in
    docs/plugins.md):

    ``options``
        ``{name: seatkit.template.Option}``: every option it accepts, with
        type, unit, default and range. A template (or recipe) giving any
        other key, or a value of the wrong type, is refused at load with the
        file, line and key path.
    ``requires``
        Names of steps that must be listed before it (``("corners",)``).
    ``stage``
        ``"blocks"``: it works on each person's faces
        (:class:`seatkit.template.Block`) and must come before any ``"grid"``
        step; ``"grid"``: it works on the joined grid
        (:class:`seatkit.template.GridMesh`, ``state.grid``).

    The template engine calls :meth:`run` with the fitting state
    (:class:`seatkit.template.FitState`) and the step's checked options
    (every option given, and the default of every other option whose
    default is not None).
    """

    name: str
    description: str
    options: Mapping[str, Any]
    requires: Sequence[str]
    stage: str

    def run(self, state: Any, *, options: Mapping[str, Any]) -> None:
        """Advance the fitting ``state`` in place."""
        ...


@runtime_checkable
class OffersStarts(Protocol):
    """A template with several starts: ``fits`` yields its valid cages in its order of preference, ``fit``'s first."""

    def fits(self, bodies: Sequence[Body], pressures: Sequence[PressureField], *, params: Mapping[str, Any] | None = None, seed: int = 0) -> Iterator[ControlMesh]: ...


@runtime_checkable
class OffersWallsAgainst(Protocol):
    """A template that rebuilds one of its cages with walls inside the hands a refused surface (its control points ``refused``) encloses; None when it has none to offer."""

    def walls_against(self, bodies: Sequence[Body], pressures: Sequence[PressureField], cage: ControlMesh, refused: np.ndarray, *, params: Mapping[str, Any] | None = None, seed: int = 0) -> ControlMesh | None: ...


@runtime_checkable
class OffersLastResort(Protocol):
    """A template with last-resort cages (the YAML engine: its steps' last-resort options applied), empty when it has none."""

    def last_resort_fits(self, bodies: Sequence[Body], pressures: Sequence[PressureField], *, params: Mapping[str, Any] | None = None, seed: int = 0) -> Iterator[ControlMesh]: ...


#: Component kinds, by the registration hook that returns them.
COMPONENT_KINDS: dict[str, type] = {
    "body_model": BodyModel,
    "pressure_solver": PressureSolver,
    "template": SupportTemplate,
    "template_step": TemplateStep,
    "refiner": Refiner,
    "exporter": Exporter,
}


#: A template step's optional capabilities (:mod:`seatkit.template.capabilities`), offered here with the
#: other interfaces; imported on first use so that importing this module stays light.
_STEP_CAPABILITIES = ("RepairsFaces", "WallsInsideHands", "HasFallback", "HasLastResort")


def __getattr__(name: str) -> Any:
    if name in _STEP_CAPABILITIES:
        from seatkit.template import capabilities

        return getattr(capabilities, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
