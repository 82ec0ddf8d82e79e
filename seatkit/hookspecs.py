"""Hook specifications: how plugins add components to seatkit.

Every hook is called with keyword arguments only (these take none). Each
registration hook is called **once per plugin manager**, when its registry
is first built (:attr:`seatkit.plugins.SeatkitPluginManager.registry`: a
build, a command, ``seatkit plugins``), and returns a list of components, or
``None`` for none. Results are **merged** (no hook is ``firstresult``): the
registry calls every plugin's implementation on its own, so that it knows
which plugin registered which component. A plugin whose hook raises, whose
component lacks a member of its protocol (:mod:`seatkit.interfaces`) or
declares options that are not :class:`seatkit.options.Option`, or that
gives a name another plugin registered first, is disabled with one problem
line naming it, the component and the member; the others keep working
(:mod:`seatkit.plugins`).

Built-in plugins (``plugins/``) implement these hooks with
:data:`seatkit.hookimpl`, exactly as a third-party plugin does. Each hook is
documented in docs/plugins.md and has a test of its own (tests/test_hooks.py);
a meta-test keeps both true for every hook.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import pluggy

if TYPE_CHECKING:  # pragma: no cover
    from seatkit.interfaces import BodyModel, Exporter, PressureSolver, Refiner, SupportTemplate, TemplateStep

hookspec = pluggy.HookspecMarker("seatkit")


@hookspec
def seatkit_register_body_models() -> "list[BodyModel] | None":
    """Register body models (:class:`seatkit.interfaces.BodyModel`).

    Called: once per plugin manager, when its registry is built.
    Returns: a list of body models (``name`` is what a recipe's
    ``bodies[].model`` and ``--body`` name), or None.
    Results: merged over every plugin; a plugin giving a name another registered first is disabled.
    """


@hookspec
def seatkit_register_pressure_solvers() -> "list[PressureSolver] | None":
    """Register pressure solvers (:class:`seatkit.interfaces.PressureSolver`).

    Called: once per plugin manager, when its registry is built.
    Returns: a list of solvers (``pressure.solver`` in a recipe,
    ``--solver`` of ``seatkit build`` and ``seatkit pressure``), or None.
    Results: merged over every plugin; a plugin giving a name another registered first is disabled.
    """


@hookspec
def seatkit_register_templates() -> "list[SupportTemplate] | None":
    """Register support templates (:class:`seatkit.interfaces.SupportTemplate`).

    Most templates are YAML files wrapped by
    :func:`seatkit.template.load_template`.

    Called: once per plugin manager, when its registry is built; after every
    plugin has registered, each template is bound to the registered template
    steps (``SupportTemplate.bind``), and one whose steps are unknown or
    misused is left out with its ``file:line`` problem reported.
    Returns: a list of templates (``template`` in a recipe, ``--template``), or None.
    Results: merged over every plugin; a plugin giving a name another registered first is disabled.
    """


@hookspec
def seatkit_register_template_steps() -> "list[TemplateStep] | None":
    """Register template fitting steps (:class:`seatkit.interfaces.TemplateStep`).

    A YAML template names steps under ``steps:``; a step declares its
    options, prerequisites and stage (see "Writing a template step" in
    docs/plugins.md).

    Called: once per plugin manager, when its registry is built, before any
    template is bound.
    Returns: a list of steps, or None.
    Results: merged over every plugin; a plugin giving a name another registered first is disabled.
    """


@hookspec
def seatkit_register_refiners() -> "list[Refiner] | None":
    """Register refiners (:class:`seatkit.interfaces.Refiner`).

    Called: once per plugin manager, when its registry is built.
    Returns: a list of refiners (``refiners`` and
    ``evaluate.baseline_refiners`` in a recipe, ``--refiner``), or None.
    A refiner declares its options (``options``: name ->
    :class:`seatkit.options.Option`); a recipe's ``params`` for it are
    checked against them before any geometry.
    Results: merged over every plugin; a plugin giving a name another registered first is disabled.
    """


@hookspec
def seatkit_register_exporters() -> "list[Exporter] | None":
    """Register exporters (:class:`seatkit.interfaces.Exporter`).

    Called: once per plugin manager, when its registry is built.
    Returns: a list of exporters (``exporters`` in a recipe, ``--exporter``), or None.
    An exporter that declares ``options`` is called
    ``export(result, directory, options=...)`` with a recipe's ``params``
    for it, checked before any geometry.
    Results: merged over every plugin; a plugin giving a name another registered first is disabled.
    """


@hookspec
def seatkit_register_pose_dirs() -> "list[Path] | None":
    """Register folders of pose YAML files for the pose library.

    Called: once per plugin manager, when its registry is built
    (``registry.pose_dirs``, which the build, ``seatkit poses``, ``seatkit
    body`` and ``seatkit pressure`` look library poses up in).
    Returns: a list of directories, or None.
    Results: merged over every plugin in registration order (a folder given
    twice counts once); a pose name defined in two folders is an error
    naming both plugins.
    """
