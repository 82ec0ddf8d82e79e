"""``seatkit body``: pose a body and write it as a mesh (and a preview PNG)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import click
import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def body(
        pose: str = typer.Option(
            "upright-sitting", "--pose", "-p", metavar="POSE",
            help="Library pose name (see 'seatkit poses'), a pose YAML file, or a .bvh file.",
        ),
        out: Path = typer.Option(..., "--out", "-o", help="Output mesh (.ply, .obj, .stl, .glb: by extension)."),
        png: Optional[Path] = typer.Option(None, "--png", help="Also write a preview picture (front and side views)."),
        body_name: str = typer.Option(
            "default-male", "--body", "-b", metavar="NAME|PATH",
            help="default-male, default-female, a seatkit .npz rig, or a registered body model (e.g. anny).",
        ),
        mass: float = typer.Option(75.0, "--mass", help="Body mass in kg."),
        frame: Optional[int] = typer.Option(None, "--frame", help="BVH frame to use (for a .bvh POSE)."),
        no_ground: bool = typer.Option(False, "--no-ground", help="Keep the pose's height instead of resting the lowest point on y = 0."),
    ) -> None:
        """Pose a body by linear blend skinning and write the mesh (metres, +Y up, facing +Z)."""
        import trimesh

        from seatkit.body import load_pose, load_rig, pose_rig
        from seatkit.errors import InputError
        from seatkit.io import write_bytes_atomic

        suffix = out.suffix.lower().lstrip(".")
        if suffix not in ("ply", "obj", "stl", "glb", "off"):
            msg = f"--out {out}: unknown mesh format {out.suffix!r}; expected .ply, .obj, .stl, .glb or .off"
            raise InputError(msg)
        rig = load_rig(body_name, mass=mass)
        posed = pose_rig(rig, load_pose(pose, frame=frame, rig=rig), ground=not no_ground)
        mesh = trimesh.Trimesh(posed.vertices, posed.faces, process=False)
        data = mesh.export(file_type=suffix)
        write_bytes_atomic(out, data.encode() if isinstance(data, str) else data)
        click.echo(
            f"{out}: {len(posed.vertices)} vertices, {len(posed.faces)} triangles, "
            f"{posed.mass:.1f} kg, hip centre at y = {posed.joints[0][1]:.3f} m"
        )
        if png is not None:
            from seatkit.body.render import render_body

            render_body(posed, png, views=("front", "side"), title=posed.name, show_skeleton=True)
            click.echo(f"{png}: preview")
