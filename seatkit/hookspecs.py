"""Hook specifications: how plugins add components to seatkit.

Every hook is called with keyword arguments only. The registration hooks
return a list of components (or ``None``); results of every plugin are merged
and a duplicate name is refused with an error that names both plugins (see
:mod:`seatkit.plugins`). Built-in plugins in ``plugins/`` use exactly these
hooks through the ``seatkit`` entry point group, as a third party would.
"""

from __future__ import annotations

from pathlib import Path

import pluggy

hookspec = pluggy.HookspecMarker("seatkit")


@hookspec
def seatkit_register_body_models() -> list:
    """Register body models (:class:`seatkit.interfaces.BodyModel`).

    Called once, when the plugin manager first builds its registry.
    Returns a list of components; every plugin's list is merged.
    """


@hookspec
def seatkit_register_pressure_solvers() -> list:
    """Register pressure solvers (:class:`seatkit.interfaces.PressureSolver`).

    Called once, when the registry is built. Returns a list; all are merged.
    """


@hookspec
def seatkit_register_templates() -> list:
    """Register support templates (:class:`seatkit.interfaces.SupportTemplate`).

    Most templates are YAML files wrapped by
    :func:`seatkit.template.load_template`. Called once, when the registry is
    built. Returns a list; all are merged.
    """


@hookspec
def seatkit_register_template_steps() -> list:
    """Register template fitting steps (:class:`seatkit.interfaces.TemplateStep`).

    A YAML template names steps under ``steps:``; a plugin can add new ones.
    Called once, when the registry is built. Returns a list; all are merged.
    """


@hookspec
def seatkit_register_refiners() -> list:
    """Register refiners (:class:`seatkit.interfaces.Refiner`).

    Called once, when the registry is built. Returns a list; all are merged.
    """


@hookspec
def seatkit_register_exporters() -> list:
    """Register exporters (:class:`seatkit.interfaces.Exporter`).

    Called once, when the registry is built. Returns a list; all are merged.
    """


@hookspec
def seatkit_register_pose_dirs() -> list[Path]:
    """Register folders of pose YAML files for the pose library.

    Called once, when the pose library is first listed. Returns a list of
    directories; a pose name defined twice is refused naming both plugins.
    """
