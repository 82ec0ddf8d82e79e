"""``seatkit evaluate DIR``: the paper's Table 1 figures for an existing build folder."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from seatkit.designs import load_checked_design  # noqa: F401  (the reader ``seatkit evaluate`` uses; its home is seatkit.designs)


def evaluate_folder(directory: Path, *, pm, baseline: str | None = "keep", support_distance: float | None = None):
    """Re-evaluate the design saved in ``directory/design.npz``.

    Returns the :class:`~seatkit.model.BuildResult` with ``metrics`` filled.
    """
    from seatkit.constants import DEFAULT_SUPPORT_DISTANCE
    from seatkit.model import BuildResult
    from seatkit.pipeline import evaluate_result, seated_importance, solve_importance
    from seatkit.subdivision import limit_surface

    recipe, bodies, mesh, initial = load_checked_design(Path(directory) / "design.npz")
    ev = recipe.setdefault("evaluate", {"enabled": True, "baseline": "flat-patch", "support_distance": DEFAULT_SUPPORT_DISTANCE})
    if baseline != "keep":
        ev["baseline"] = baseline
    if support_distance is not None:
        ev["support_distance"] = support_distance
    registry = pm.registry
    pressures = seated_importance(recipe, bodies, solve_importance(recipe, bodies, registry), registry)  # sitters lifted off the floor (seatkit.sitters)
    result = BuildResult(
        recipe=recipe,
        bodies=bodies,
        pressures=pressures,
        initial_mesh=initial,
        control_mesh=mesh,
        surface=limit_surface(mesh, level=recipe.get("surface_level", 3)),
    )
    evaluate_result(result, registry)
    return result


def register(app: typer.Typer) -> None:
    from seatkit.cli import plugin_manager

    @app.command()
    def evaluate(
        ctx: typer.Context,
        directory: Path = typer.Argument(..., help="A seatkit build folder (it holds design.npz)."),
        baseline: Optional[str] = typer.Option(
            None, "--baseline", help="Baseline template to compare with (default: the build's, flat-patch); 'none' for no baseline."
        ),
        support_distance: Optional[float] = typer.Option(None, "--support-distance", help="Contact distance in m (default 0.02)."),
        as_json: bool = typer.Option(False, "--json", help="Print the metrics as JSON."),
    ) -> None:
        """Recompute pressure on the designed surface and print the paper's Table 1 figures.

        Writes DIR/evaluation.json. Our design is compared with the flat-patch
        baseline refined the same way.
        """
        from seatkit.export.report import person_labels, table_rows
        from seatkit.io import write_text_atomic
        from seatkit.io import jsonable
        from seatkit.metrics import CHECKS_NOTE, TABLE_CAPTION

        pm = plugin_manager(ctx)
        base = "keep" if baseline is None else (None if baseline.lower() == "none" else baseline)
        result = evaluate_folder(directory, pm=pm, baseline=base, support_distance=support_distance)
        metrics = jsonable(result.metrics)
        write_text_atomic(Path(directory) / "evaluation.json", json.dumps(metrics, indent=1) + "\n")
        if as_json:
            typer.echo(json.dumps(metrics, indent=1))
            return
        from rich.console import Console
        from rich.table import Table

        console = Console()
        # the rows the report's pictures and report.html show (seatkit.export.report.table_rows)
        rows, labels = table_rows(metrics, person_labels(result.bodies))
        for i, (person, ours_cells, base_cells) in enumerate(rows):
            ours = metrics["ours"][i] if i < len(metrics["ours"]) else {}
            table = Table(title=person, show_edge=False)
            table.add_column(TABLE_CAPTION)
            table.add_column("ours", justify="right")
            if metrics.get("baseline"):
                table.add_column(metrics["baseline_template"], justify="right")
            if not ours.get("supported", True):
                console.print(f"{person}: our surface cannot hold this person: {ours.get('reason')}")
            for label, a, b in zip(labels, ours_cells, base_cells):
                table.add_row(label, a, *([b] if metrics.get("baseline") else []))
            console.print(table)
        console.print(CHECKS_NOTE)
        console.print(f"wrote {Path(directory) / 'evaluation.json'}")
