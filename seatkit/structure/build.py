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

from seatkit.errors import SeatkitError
from seatkit.io import jsonable
from seatkit.structure.analysis import (
    DEFAULT_LAYERS,
    DEFAULT_LEVEL,
    DEFAULT_MAX_DEFLECTION,
    DEFAULT_SAFETY_FACTOR,
    Analysis,
    StructureError,
    analyse,
    check_thickness,
    size_thickness,
)
from seatkit.structure.materials import get_material

__all__ = ["DEFAULTS", "SCHEMA", "StructureExporter", "enable", "run_structure", "settings", "write_structure"]

DEFAULT_MATERIAL = "birch-plywood"
DEFAULT_THICKNESS = 0.02

DEFAULTS = {
    "enabled": False,
    "material": DEFAULT_MATERIAL,
    "thickness": DEFAULT_THICKNESS,
    "size_thickness": False,
    "safety_factor": DEFAULT_SAFETY_FACTOR,
    "max_deflection": DEFAULT_MAX_DEFLECTION,
    "level": DEFAULT_LEVEL,
    "layers": DEFAULT_LAYERS,
}

_POSITIVE = {"type": "number", "exclusiveMinimum": 0}

#: JSON schema of the recipe's ``structure`` section.
SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "enabled": {"type": "boolean"},
        "material": {"type": "string", "minLength": 1},
        "thickness": _POSITIVE,
        "size_thickness": {"type": "boolean"},
        "safety_factor": _POSITIVE,
        "max_deflection": _POSITIVE,
        "level": {"type": "integer", "minimum": 1, "maximum": 3},
        "layers": {"type": "integer", "minimum": 1, "maximum": 4},
    },
}

#: Exporters a build with the analysis gets.
EXPORTERS = ("structure", "shell")


def settings(data=None) -> dict:
    """The ``structure`` section with every key filled in (defaults: :data:`DEFAULTS`)."""
    out = dict(DEFAULTS)
    out.update({k: v for k, v in dict(data or {}).items() if v is not None})
    return out


def check(section: dict) -> list[tuple[str, str]]:
    """Problems of a filled ``structure`` section: (key, message) pairs."""
    problems = []
    try:
        get_material(section["material"])
    except SeatkitError as e:
        problems.append(("material", str(e)))
    try:
        check_thickness(section["thickness"])
    except StructureError as e:
        problems.append(("thickness", str(e)))
    for key, what in (("safety_factor", "a positive number (e.g. 2)"), ("max_deflection", "a positive number of metres (e.g. 0.01)")):
        value = section[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0 < value < float("inf")):
            problems.append((key, f"expected {what}, got {value!r}"))
    for key, top in (("level", 3), ("layers", 4)):
        value = section[key]
        if isinstance(value, bool) or not isinstance(value, int) or not (1 <= value <= top):
            problems.append((key, f"expected a whole number from 1 to {top}, got {value!r}"))
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


class StructureExporter:
    """``structure.json`` and ``structure.png``: will the shell hold its people (docs/structure.md)."""

    name = "structure"
    description = "structure.json/.png: stress, safety factor and deflection of the shell under its people (FEM)"
    #: Runs in the build's process: the analysis it may run needs the result's evaluation, not a pickled copy.
    prepare_ahead = False

    def prepare(self) -> None:
        """Nothing to prepare: scikit-fem is imported when an analysis runs."""

    def export(self, result, directory: Path) -> dict[str, Path]:
        analysis = result.structure
        if analysis is None:  # listed as an exporter without the build step: analyse now
            analysis = analyse_result(result)
        return write_structure(analysis, directory, title=_title(result))


def _title(result) -> str:
    recipe = result.recipe or {}
    people = len(result.bodies or [])
    return f"{recipe.get('template', 'design')}, {people} {'person' if people == 1 else 'people'}"
