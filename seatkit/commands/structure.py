"""``seatkit structure DIR``: will the shell of an existing build hold its people?"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer


def structure_folder(directory: Path, *, pm, out: Path | None = None, **flags):
    """Analyse the design in ``directory`` and write ``structure.json``/``.png`` into ``out`` (default ``directory``).

    The people's contact forces are recomputed on the design as
    ``seatkit evaluate`` does (without the baseline). ``flags`` are the
    recipe's ``structure`` keys (None: the build's setting, else the
    default). With ``size_thickness`` the shell is written too, at the thickness found.

    Returns
    -------
    analysis : seatkit.structure.Analysis
    files : dict of str to Path
    """
    from seatkit.commands.evaluate import evaluate_folder
    from seatkit.structure.build import analyse_result, check, settings, write_structure
    from seatkit.structure.build import _title as title_of
    from seatkit.structure import StructureError

    directory = Path(directory)
    out = Path(out) if out is not None else directory
    if not (directory / "design.npz").is_file():
        msg = f"{directory}: not a seatkit build folder (no design.npz); build one with seatkit build"
        raise StructureError(msg)
    from seatkit.state import load_design

    recipe = load_design(directory / "design.npz")[0]
    section = settings({**recipe.get("structure", {}), **{k: v for k, v in flags.items() if v is not None}})
    for key, message in check(section):
        raise StructureError(f"--{key.replace('_', '-')}: {message}")
    result = evaluate_folder(directory, pm=pm, baseline=None)
    try:
        analysis = analyse_result(result, section)
    except StructureError as e:  # the design cannot be analysed (off the floor, ...): name its file
        raise StructureError(f"{directory / 'design.npz'}: {e}") from None
    out.mkdir(parents=True, exist_ok=True)
    files = write_structure(analysis, out, title=title_of(result))
    if section["size_thickness"]:
        from seatkit.export.meshes import write_shell

        files["shell_stl"] = write_shell(result.surface, analysis.summary["thickness_m"], out / "shell.stl")
    return analysis, files


def register(app: typer.Typer) -> None:
    from seatkit.cli import plugin_manager

    @app.command()
    def structure(
        ctx: typer.Context,
        directory: Path = typer.Argument(..., help="A seatkit build folder (it holds design.npz)."),
        out: Optional[Path] = typer.Option(None, "--out", "-o", help="Folder for structure.json/.png (default DIR)."),
        material: Optional[str] = typer.Option(None, "--material", help="Shell material (default birch-plywood; see docs/structure.md)."),
        thickness: Optional[float] = typer.Option(None, "--thickness", help="Shell thickness in m (default 0.02)."),
        size_thickness: bool = typer.Option(False, "--size-thickness", help="Find the thinnest shell that keeps the limits; write shell.stl."),
        safety_factor: Optional[float] = typer.Option(None, "--safety-factor", help="Safety factor to keep (default 2)."),
        max_deflection: Optional[float] = typer.Option(None, "--max-deflection", help="Deflection limit in m (default 0.01)."),
        level: Optional[int] = typer.Option(None, "--level", help="Mesh resolution: elements are the level-L quads (1-3, default 2)."),
        layers: Optional[int] = typer.Option(None, "--layers", help="Quadratic elements through the thickness (1-4, default 1)."),
        as_json: bool = typer.Option(False, "--json", help="Print structure.json on stdout."),
    ) -> None:
        """Stress, safety factor and deflection of the designed shell under its people (FEM).

        Loads: each person's contact pressure and friction on the designed
        surface, and the shell's own weight; held where it meets the floor.
        Writes structure.json and structure.png (docs/structure.md).
        """
        pm = plugin_manager(ctx)
        analysis, files = structure_folder(
            directory,
            pm=pm,
            out=out,
            material=material,
            thickness=thickness,
            size_thickness=size_thickness or None,
            safety_factor=safety_factor,
            max_deflection=max_deflection,
            level=level,
            layers=layers,
        )
        s = analysis.summary
        if as_json:
            typer.echo(Path(files["structure_json"]).read_text(), nl=False)
            return
        from rich.console import Console
        from rich.table import Table

        table = Table(title=f"seatkit structure: {s['material']}, {s['thickness_m'] * 1000:.1f} mm", show_edge=False, show_header=False)
        table.add_column("")
        table.add_column("", justify="right")
        rows = [
            ("max von Mises stress", f"{s['max_von_mises_pa'] / 1e6:.3f} MPa"),
            ("strength", f"{s['strength_pa'] / 1e6:.0f} MPa"),
            ("safety factor", f"{s['safety_factor']:.2f}"),
            ("max deflection", f"{s['max_deflection_m'] * 1000:.3f} mm"),
            ("mass", f"{s['mass_kg']:.2f} kg"),
            ("applied load", f"{s['applied_load_n']:.1f} N"),
            ("floor reaction", f"{s['floor_reaction_n']:.1f} N"),
        ]
        if "sizing" in s:
            z = s["sizing"]
            rows.append(("sized for", f"safety factor {z['safety_factor']:g}, deflection {z['max_deflection_m'] * 1000:g} mm ({z['governed_by']})"))
        for row in rows:
            table.add_row(*row)
        console = Console()
        console.print(table)
        if s["distorted_elements"]:
            console.print(
                f"note: {s['distorted_elements']} elements are folded or nearly ({s['distorted_volume_fraction'] * 100:.1f}% of the volume): "
                "the surface curls tighter than the shell is thick there; their stress is left out (docs/structure.md)"
            )
        console.print(f"wrote {', '.join(str(p) for p in files.values())}")
