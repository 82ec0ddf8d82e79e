"""``seatkit evaluate DIR``: the paper's Table 1 figures for an existing build folder."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import click
import typer


def load_checked_design(path):
    """:func:`seatkit.state.load_design`, its recipe checked as ``seatkit evaluate`` uses it.

    The recipe must pass the recipe schema (it is returned normalised, every
    key present), and its ``surface_level`` must not refine the final cage
    past :data:`~seatkit.subdivision.catmull_clark.MAX_REFINED_FACES` quads.

    Raises
    ------
    InputError
        One line naming the file and the recipe's key.
    """
    from seatkit.errors import InputError, SeatkitError
    from seatkit.messages import one_line
    from seatkit.recipe import RECIPE_SCHEMA, load_recipe
    from seatkit.subdivision.catmull_clark import MAX_REFINED_FACES
    from seatkit.state import load_design
    from seatkit.yamlio import Document, validate

    path = Path(path)
    recipe, bodies, mesh, initial = load_design(path)  # lambda "inf" read as the number
    try:
        validate(Document(recipe, f"{path}: header.recipe"), RECIPE_SCHEMA)
        recipe, _ = load_recipe(recipe)  # normalised: every key evaluate reads is present
    except SeatkitError as e:
        raise InputError(one_line(f"{path}: header.recipe: {e}" if not str(e).startswith(str(path)) else str(e))) from None
    level = recipe.get("surface_level", 3)
    quads = 4 * len(mesh.faces) * 4 ** (level - 1)  # evaluate refines the final quad cage this far
    if quads > MAX_REFINED_FACES:
        raise InputError(f"{path}: header.recipe.surface_level: {level} refines the cage past {MAX_REFINED_FACES:,} quads")
    return recipe, bodies, mesh, initial


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
            click.echo(json.dumps(metrics, indent=1))
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
