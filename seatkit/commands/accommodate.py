"""``seatkit accommodate DESIGN_DIR``: the share of a sampled population a design accommodates, on Dask."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def accommodate(
        directory: Path = typer.Argument(..., help="A seatkit build folder (it holds design.npz and report.json)."),
        population: str = typer.Option("ansur-ii", "--population", help="Survey to sample from (ansur-ii)."),
        n: int = typer.Option(100, "--n", help="Number of people to sample."),
        out: Optional[Path] = typer.Option(None, "--out", "-o", help="Study folder (default DESIGN_DIR-accommodation)."),
        pose: str = typer.Option("upright-sitting", "--pose", "-p", help="The pose every person sits in."),
        seed: int = typer.Option(0, "--seed", help="Sampling seed; the same seed and N give the same people."),
        female_share: float = typer.Option(0.5, "--female-share", help="Share of women in the sample (0 to 1)."),
        pressure_ratio: float = typer.Option(2.0, "--pressure-ratio", help="Peak pressure limit, times the design's own sitters'."),
        moment_ratio: float = typer.Option(2.0, "--moment-ratio", help="Joint moment limit, times the design's own sitters'."),
        reference: Optional[Path] = typer.Option(
            None, "--reference",
            help="A build folder whose own sitters' peak pressure and joint moment set the limits instead of the design's (compare designs under the same limits).",
        ),
        scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Address of an existing Dask scheduler."),
        workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes (default: one per core)."),
    ) -> None:
        """Sample people from a survey, seat each on the design (seatkit trial) on Dask, and report who it accommodates.

        Writes OUT/accommodation.json, people.csv, not-accommodated.csv and
        accommodation.png; running it again resumes where it stopped.
        """
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        from seatkit.errors import InputError
        from seatkit.population import Criteria, run_accommodation, share_text

        for name, value in (("--pressure-ratio", pressure_ratio), ("--moment-ratio", moment_ratio)):
            if not value > 0:
                raise InputError(f"{name}: expected a positive number, got {value:g}")
        folder = out if out is not None else Path(f"{Path(directory).resolve()}-accommodation")
        criteria = Criteria(pressure_ratio=pressure_ratio, moment_ratio=moment_ratio)
        with Progress(TextColumn("[bold]accommodate"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), transient=True) as bar:
            task = bar.add_task("", total=max(n, 1))
            summary = run_accommodation(
                directory, folder, n=n, population=population, seed=seed, female_share=female_share, pose=pose,
                criteria=criteria, scheduler=scheduler, workers=workers, reference=reference,
                progress=lambda done, total: bar.update(task, completed=done, total=total),
            )
        typer.echo(share_text(summary))
        sole = summary["sole_reasons"]
        for reason, count in summary["reasons"].items():
            typer.echo(f"  {count} {reason}" + (f" ({sole[reason]} for this reason alone)" if reason in sole else ""))
        typer.echo(f"{folder / 'accommodation.json'}")
