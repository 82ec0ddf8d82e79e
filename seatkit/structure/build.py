"""The structural analysis as a step of a build and as files.

A recipe's ``structure`` section (all keys optional)::

    structure:
      enabled: true            # run the analysis in the build (seatkit build --structure)
      material: birch-plywood  # one of seatkit.structure.MATERIALS
      thickness: 0.02          # m; also the thickness the shell exporter writes
      size_thickness: false    # find the thinnest shell that keeps the two limits below
      safety_factor: 2         # the limits --size-thickness keeps
      max_deflection: 0.01     # m
      level: 2                 # mesh resolution (elements: the level-L quads), layers
      layers: 1

With ``enabled`` the build analyses the design after its evaluation
(:func:`run_structure`) and adds the ``structure`` exporter
(``structure.json``, ``structure.png``) and the ``shell`` exporter, which
writes the analysed (or sized) thickness.
"""

from __future__ import annotations

import json
from pathlib import Path

from seatkit.errors import ParamError
from seatkit.options import Option, check_options, defaults, json_schema
from seatkit.io import jsonable
from seatkit.structure.analysis import (
    DEFAULT_LAYERS,
    DEFAULT_LEVEL,
    DEFAULT_MAX_DEFLECTION,
    DEFAULT_SAFETY_FACTOR,
    Analysis,
    StructureError,
    analyse,
    size_thickness,
)
from seatkit.structure.materials import MATERIALS

__all__ = ["DEFAULTS", "OPTIONS", "SCHEMA", "enable", "run_structure", "settings", "write_structure"]

DEFAULT_MATERIAL = "birch-plywood"
DEFAULT_THICKNESS = 0.02

#: Options of the ``structure`` section: their one declaration (:mod:`seatkit.options`).
OPTIONS: dict[str, Option] = {
    "enabled": Option("bool", "run the analysis in the build (seatkit build --structure)", False),
    "material": Option("choice", "shell material (seatkit.structure.MATERIALS)", DEFAULT_MATERIAL, choices=tuple(MATERIALS)),
    "thickness": Option("number", "shell thickness; also the thickness the shell exporter writes", DEFAULT_THICKNESS, "m", 1e-4, 0.5),
    "size_thickness": Option("bool", "find the thinnest shell that keeps safety_factor and max_deflection", False),
    "safety_factor": Option("number", "safety factor --size-thickness keeps", DEFAULT_SAFETY_FACTOR, "1", 1e-3, 1e3),
    "max_deflection": Option("number", "deflection limit --size-thickness keeps", DEFAULT_MAX_DEFLECTION, "m", 1e-6, 1.0),
    "level": Option("count", "mesh resolution: the elements are the level-L quads", DEFAULT_LEVEL, "", 1, 3),
    "layers": Option("count", "elements through the thickness", DEFAULT_LAYERS, "", 1, 4),
}

#: Defaults of the ``structure`` section (from :data:`OPTIONS`).
DEFAULTS = defaults(OPTIONS)

#: JSON schema of the recipe's ``structure`` section (from :data:`OPTIONS`).
SCHEMA = json_schema(OPTIONS)

#: Exporters a build with the analysis gets.
EXPORTERS = ("structure", "shell")


def settings(data=None) -> dict:
    """The ``structure`` section with every key filled in (defaults: :data:`DEFAULTS`)."""
    out = dict(DEFAULTS)
    out.update({k: v for k, v in dict(data or {}).items() if v is not None})
    return out


def check(section: dict) -> list[tuple[str, str]]:
    """Problems of a filled ``structure`` section (from a file or flags): (key, message) pairs, against :data:`OPTIONS`."""
    problems = []
    for key, value in section.items():
        try:
            check_options("structure", OPTIONS, {key: value}, fail=ParamError)
        except ParamError as e:
            problems.append((key, e.problem))
    return problems


def enable(recipe: dict, **flags) -> dict:
    """``recipe`` with the analysis switched on, ``flags`` (None: keep) applied and its exporters added."""
    section = settings({**recipe.get("structure", {}), **{k: v for k, v in flags.items() if v is not None}})
    section["enabled"] = True
    recipe["structure"] = section
    for name in EXPORTERS:
        if name not in recipe["exporters"]:
            recipe["exporters"].append(name)
    return recipe


def analyse_result(result, section: dict | None = None) -> Analysis:
    """Analyse (or size) a build result's design with a ``structure`` section's settings."""
    s = settings(section if section is not None else (result.recipe or {}).get("structure"))
    fields = result.contact_pressures
    if fields is None:
        msg = "the structural analysis needs the evaluation's contact forces: do not switch the evaluation off"
        raise StructureError(msg)
    common = dict(material=s["material"], level=s["level"], layers=s["layers"])
    if s["size_thickness"]:
        analysis, _ = size_thickness(
            result.control_mesh,
            result.bodies,
            fields,
            safety_factor=s["safety_factor"],
            max_deflection=s["max_deflection"],
            start=s["thickness"],
            **common,
        )
    else:
        analysis = analyse(result.control_mesh, result.bodies, fields, thickness=s["thickness"], **common)
    return analysis


def run_structure(result) -> Analysis:
    """The build's step: analyse, keep the analysis and its figures in the result, set the shell's thickness."""
    analysis = analyse_result(result)
    result.structure = analysis
    result.shell_thickness_m = analysis.summary["thickness_m"]
    result.metrics["structure"] = jsonable(analysis.summary)
    return analysis


def write_structure(analysis: Analysis, directory, *, title: str = "") -> dict[str, Path]:
    """``structure.json`` and ``structure.png`` of an analysis in ``directory`` (each written atomically)."""
    from seatkit.io import write_text_atomic
    from seatkit.structure.picture import write_stress_png

    directory = Path(directory)
    json_path = write_text_atomic(directory / "structure.json", json.dumps(jsonable(analysis.summary), indent=1) + "\n")
    png = write_stress_png(analysis, directory / "structure.png", title=title)
    return {"structure_json": Path(json_path), "structure_png": png}


def _title(result) -> str:
    recipe = result.recipe or {}
    people = len(result.bodies or [])
    return f"{recipe.get('template', 'design')}, {people} {'person' if people == 1 else 'people'}"
