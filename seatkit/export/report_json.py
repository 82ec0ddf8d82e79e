"""``report.json``: what one build ran and produced, for people and scripts.

The ``report-json`` exporter (registered by the ``seatkit_exporters`` plugin
like every other exporter) runs last in every writing build, after the
recipe's exporters, whether or not the recipe lists it: it records the files
they wrote and the time each stage took, the export stage included. It also
puts the final time table into ``report.html`` when the build wrote one
(that page is written before the export stage's time is known). The keys are
in docs/output.md.
"""

from __future__ import annotations

import functools
import json
import platform
from pathlib import Path

import numpy as np

from seatkit.constants import DEFAULT_MU
from seatkit.io import jsonable, write_text_atomic
from seatkit.pressure.compliant import friction_state

__all__ = ["REPORT_EXPORTER", "ReportJsonExporter", "report_data", "versions", "FIGURE_MODELS", "IMPORTANCE_MEANING"]

#: The registered name of the exporter of report.json.
REPORT_EXPORTER = "report-json"

#: Distributions whose versions report.json records.
_DISTRIBUTIONS = ("seatkit", "numpy", "scipy", "pluggy", "qpsolvers", "piqp", "usd-core", "trimesh")


#: What the importance figures are (report.json ``pressure[i].meaning``).
IMPORTANCE_MEANING = (
    "relative importance (the paper's Section 4 model, supported everywhere): how a support should share the weight, "
    "in Pa but not an interface pressure"
)

#: Each pressure figure of report.json: its model, meaning and unit.
FIGURE_MODELS = {
    "pressure": {"model": "paper-qp", "meaning": IMPORTANCE_MEANING, "unit": "Pa"},
    "metrics.ours / metrics.baseline (avg_pressure_pa, max_pressure_pa)": {
        "model": "paper-qp",
        "meaning": "the paper's Table 1: its model re-solved on the body's contact with the design, a relative importance",
        "unit": "Pa",
    },
    "metrics.interface": {
        "model": "winkler-soft-tissue",
        "meaning": "interface pressure: soft tissue over the skeleton on the rigid design, comparable with a pressure mat "
        "(docs/physics.md, validation)",
        "unit": "Pa; load_share a fraction of the body weight",
    },
}


def versions() -> dict:
    """Python's version and those of seatkit and the libraries its results depend on (those this process runs: read once)."""
    return dict(_versions())


@functools.lru_cache(maxsize=1)
def _versions() -> tuple:
    import importlib.metadata as md

    out = [("python", platform.python_version())]
    for dist in _DISTRIBUTIONS:
        try:
            out.append((dist, md.version(dist)))
        except md.PackageNotFoundError:
            pass
    return tuple(out)


def report_data(result) -> dict:
    """report.json's content for a build result whose other files are written (``result.files``)."""
    from seatkit.io import recipe_id

    mesh = result.control_mesh
    meta = {k: v for k, v in mesh.meta.items() if k != "search"}
    return {
        "seatkit_run": recipe_id(result.recipe),
        "recipe": jsonable(result.recipe),
        "versions": versions(),
        "timings_s": jsonable(result.timings),
        "control_mesh": {
            "vertices": int(len(mesh.vertices)),
            "faces": int(len(mesh.faces)),
            "meta": jsonable(meta),
        },
        # the design search (seatkit.search): the winning candidate's origin, every rejected candidate's reason
        "search": jsonable(mesh.meta.get("search")),
        "pressure": [
            {
                "model": "paper-qp",
                "meaning": IMPORTANCE_MEANING,
                "status": pf.status,
                "solve_seconds": pf.solve_seconds,
                "max_pressure_pa": float(pf.pressure.max()),
                "max_joint_moment_nm": float(np.linalg.norm(pf.joint_moment, axis=1).max()),
                "friction": friction_state(pf, mu=pf.params.get("mu", DEFAULT_MU)),
            }
            for pf in result.pressures
        ],
        "figures": FIGURE_MODELS,
        "metrics": jsonable(result.metrics),
        "frame": frame_report(result),
        "files": {k: Path(v).name for k, v in result.files.items()},
    }


def frame_report(result) -> dict:
    """report.json's ``frame``: the frame the files are in and, per person, the move into the design's frame.

    The design is fitted in the canonical frame (each person facing +Z,
    the hip joints' midpoint above the origin; :mod:`seatkit.body.frame`);
    ``people[i]`` says how person i's capture was turned and shifted into
    it (before the seat placement). ``export`` is ``capture`` when the
    geometry files were moved back into the capture's frame.
    """
    export = result.recipe.get("export_frame") or "canonical"
    return {
        "design": "canonical: +Y up, each person facing +Z, hip joints' midpoint above the origin",
        "export": export,
        "people": [f.report() for f in (result.frames or [])],
    }


class ReportJsonExporter:
    """``report.json``: the recipe, versions, timings, cage size, pressure figures, metrics and files."""

    name = REPORT_EXPORTER
    description = "report.json: recipe, versions, time per stage, metrics and the files written (every build writes it, last)"

    prepare_ahead = False

    def prepare(self) -> None:
        """Read the libraries' versions (:func:`versions`), ahead of :meth:`export`: a build does it while its helpers finish."""
        versions()

    def export(self, result, directory: Path) -> dict[str, Path]:
        directory = Path(directory)
        html = directory / "report.html"
        if "report_html" in result.files and html.exists():
            from seatkit.export.report import finish_report_html

            finish_report_html(html, result.timings)  # the export stage's time, and the total
        return {"report": write_text_atomic(directory / "report.json", json.dumps(report_data(result), indent=1) + "\n")}
