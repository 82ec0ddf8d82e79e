"""``seatkit trial DESIGN_DIR``: seat a person the design was not made for, and report its figures."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer


def default_trial_folder(design: Path, body: str, pose: str) -> Path:
    """``trials/DESIGN--BODY--POSE`` in the working folder (names made safe for a folder)."""
    from seatkit.batch import _safe_name

    return Path("trials") / _safe_name(f"{Path(design).resolve().name}--{body}--{Path(pose).stem}")


def register(app: typer.Typer) -> None:
    @app.command()
    def trial(
        ctx: typer.Context,
        directory: Path = typer.Argument(..., help="A seatkit build folder (it holds design.npz)."),
        body: str = typer.Option("default-male", "--body", "-b", metavar="BODY", help="Body as in 'seatkit build' (a preset, default-female:height=1.6,mass=60, a file)."),
        pose: str = typer.Option("upright-sitting", "--pose", "-p", metavar="POSE", help="Library pose name, pose YAML or BVH."),
        mass: Optional[float] = typer.Option(None, "--mass", help="Body mass in kg (default the body's)."),
        height: Optional[float] = typer.Option(None, "--height", help="Stature in m (parametric bodies)."),
        frame: Optional[int] = typer.Option(None, "--frame", help="Frame of a BVH pose."),
        seat: int = typer.Option(1, "--seat", help="Which sitter's place of the design (1 = the first; a bench has several)."),
        out: Optional[Path] = typer.Option(None, "--out", "-o", help="Trial folder (default trials/DESIGN--BODY--POSE)."),
        as_json: bool = typer.Option(False, "--json", help="Print trial.json on stdout."),
    ) -> None:
        """Seat a person on a finished design (placement, pressure on its contact set) and report the figures.

        Writes OUT/trial.json and OUT/trial.png (the body on the surface, coloured by its contact pressure).
        """
        import json

        from seatkit.cli import plugin_manager
        from seatkit.recipe import parse_body_spec
        from seatkit.trial import load_trial_design, run_trial, trial_report, write_trial

        registry = plugin_manager(ctx).registry
        design = load_trial_design(directory)  # one line for a missing or broken design, before any work
        spec = parse_body_spec(body)
        params = dict(spec["params"])
        if mass is not None:
            params["mass"] = mass
        if height is not None:
            params["height"] = height
        result = run_trial(design, registry, spec["model"], params, pose, frame=frame or 0, seat=seat - 1, label={"pose": pose, "seat": seat})
        folder = out if out is not None else default_trial_folder(directory, body, pose)
        files = write_trial(design, result, folder)
        report = trial_report(design, result)
        if as_json:
            typer.echo(json.dumps(report, indent=1))
            return
        m, fit, pl = report["metrics"], report["person_fit"], report["placement"]
        t = pl["translation_m"]
        typer.echo(
            f"{result.body.name} on {Path(directory).name}: placed by ({t[0] * 1000:+.0f}, {t[1] * 1000:+.0f}, {t[2] * 1000:+.0f}) mm, "
            f"hip {pl['hip_flexion_deg']:+.1f} deg, knee {pl['knee_flexion_deg']:+.1f} deg, back {pl['back_recline_deg']:+.1f} deg"
        )
        if not m.get("supported"):
            typer.echo(f"the design cannot hold this person: {m.get('reason')}")
        else:
            typer.echo(
                f"avg distance {m['avg_distance_m'] * 1000:.1f} mm, max pressure {m['max_pressure_pa'] / 1000:.1f} kPa, "
                f"max joint moment {m['max_moment_nm']:.1f} N m, penetration {m['max_penetration_m'] * 1000:.1f} mm, "
                f"body depth {m['max_body_depth_m'] * 1000:.1f} mm"
            )
        if fit.get("popliteal_height_m") is not None and fit.get("seat_height_m") is not None:
            typer.echo(
                f"seat height {fit['seat_height_m'] * 1000:.0f} mm vs popliteal height + shoes {fit['seat_height_for_shoes_m'] * 1000:.0f} mm "
                f"({fit['seat_height_difference_m'] * 1000:+.0f} mm)"
            )
        for f in files.values():
            typer.echo(str(f))
