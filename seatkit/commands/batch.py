"""``seatkit batch`` and ``seatkit sweep``: many builds on Dask."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer


def _progress_runner(items, out, scheduler, workers, disabled=()):
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from seatkit.batch import run_batch

    with Progress(
        TextColumn("[bold]batch"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), TextColumn("{task.description}")
    ) as bar:
        task = bar.add_task("", total=len(items))

        def report(done, total, res):
            bar.update(task, completed=done, description=f"{res.name}: {res.status}")

        return run_batch(items, out, scheduler=scheduler, workers=workers, progress=report, disabled=disabled)


def _print_outcome(results, out: Path) -> None:
    failed = [r for r in results if r.status == "failed"]
    for r in failed:
        typer.echo(f"failed: {r.name}: {r.error}", err=True)
    counts = {s: sum(r.status == s for r in results) for s in ("ok", "skipped", "failed")}
    typer.echo(f"{counts['ok']} built, {counts['skipped']} already complete, {counts['failed']} failed; summary: {out / 'summary.csv'}")
    if failed:  # scripts must be able to tell: exit 1 when any item failed
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    from seatkit.cli import plugin_manager

    @app.command()
    def batch(
        ctx: typer.Context,
        items: List[Path] = typer.Argument(..., help="Recipes, pose files (YAML/BVH), folders of them, or a CSV/YAML table."),
        out: Path = typer.Option(..., "--out", "-o", help="Batch folder: one sub-folder per item, summary.csv, summary.png."),
        template: Optional[str] = typer.Option(None, "--template", "-t", help="Template for pose files and tables (default chair)."),
        scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Address of an existing Dask scheduler."),
        workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes (default: one per core)."),
        seed: int = typer.Option(0, "--seed", help="Batch seed; every item gets its own seed from it and its name."),
    ) -> None:
        """Run many builds on Dask; re-running skips the items already complete."""
        from seatkit.batch import collect_items
        from seatkit.recipe import check_recipe

        pm = plugin_manager(ctx)
        found = collect_items(items, template=template, out=out, seed=seed)
        for it in found:
            check_recipe(it.recipe, pm.registry)
        results = _progress_runner(found, out, scheduler, workers, pm.disabled)
        _print_outcome(results, out)

    @app.command()
    def sweep(
        ctx: typer.Context,
        template: str = typer.Option("chair", "--template", "-t"),
        pose: str = typer.Option("upright-sitting", "--pose", "-p"),
        body: str = typer.Option("default-male", "--body", "-b", help="Body model: default-male/-female (vary height, mass, sitting_height ...), a preset (height, mass), or anny."),
        vary: List[str] = typer.Option(..., "--vary", help="NAME=LOW:HIGH:COUNT, e.g. height=1.50:1.95:4 --vary mass=55:110:5 (repeatable)."),
        out: Path = typer.Option(..., "--out", "-o"),
        scheduler: Optional[str] = typer.Option(None, "--scheduler"),
        workers: Optional[int] = typer.Option(None, "--workers"),
        seed: int = typer.Option(0, "--seed"),
    ) -> None:
        """Build one design per body of a population grid and summarise comfort across it."""
        from seatkit.batch import parse_vary, sweep_items
        from seatkit.recipe import check_recipe

        pm = plugin_manager(ctx)
        grid = dict(parse_vary(v) for v in vary)
        found = sweep_items(template=template, pose=pose, body=body, vary=grid, out=out, seed=seed)
        for it in found:
            check_recipe(it.recipe, pm.registry)
        results = _progress_runner(found, out, scheduler, workers, pm.disabled)
        _print_outcome(results, out)
