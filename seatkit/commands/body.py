"""``seatkit body``: pose a body and write it as a mesh (and a preview PNG)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def body(
        ctx: typer.Context,
        pose: str = typer.Option(
            "upright-sitting", "--pose", "-p", metavar="POSE",
            help="Library pose name (see 'seatkit poses'), a pose YAML file, or a .bvh file.",
        ),
        out: Optional[Path] = typer.Option(None, "--out", "-o", help="Output mesh (.ply, .obj, .stl, .glb: by extension)."),
        png: Optional[Path] = typer.Option(None, "--png", help="Also write a preview picture (front and side views)."),
        body_name: str = typer.Option(
            "default-male", "--body", "-b", metavar="NAME|PATH",
            help="default-male, default-female, p5-female ... p95-male, a .npz rig or .glb body, or MODEL:key=value,... (e.g. default-female:height=1.55).",
        ),
        mass: Optional[float] = typer.Option(None, "--mass", help="Body mass in kg (default the body's: 75 default-male, 55 default-female, a preset's)."),
        height: Optional[float] = typer.Option(None, "--height", help="Stature in m (parametric bodies: default-*, p*-*)."),
        measure: bool = typer.Option(False, "--measure", help="Print the body's survey measurements (docs/bodies.md)."),
        frame: Optional[int] = typer.Option(None, "--frame", help="BVH frame to use (for a .bvh POSE)."),
        no_ground: bool = typer.Option(False, "--no-ground", help="Keep the pose's height instead of resting the lowest point on y = 0."),
    ) -> None:
        """Pose a body by linear blend skinning and write the mesh (metres, +Y up, facing +Z)."""
        import trimesh

        from seatkit.body import load_pose
        from seatkit.cli import plugin_manager
        from seatkit.errors import InputError
        from seatkit.recipe import parse_body_spec
        from seatkit.io import write_bytes_atomic

        if out is None and not measure:
            msg = "seatkit body: give --out FILE (a mesh), --measure, or both"
            raise InputError(msg)
        suffix = out.suffix.lower().lstrip(".") if out is not None else ""
        if out is not None and suffix not in ("ply", "obj", "stl", "glb", "off"):
            msg = f"--out {out}: unknown mesh format {out.suffix!r}; expected .ply, .obj, .stl, .glb or .off"
            raise InputError(msg)
        spec = parse_body_spec(body_name)
        registry = plugin_manager(ctx).registry
        model = registry.get("body_model", spec["model"])
        extra = {k: v for k, v in (("mass", mass), ("height", height)) if v is not None}
        rig = model.make_body(params={**spec["params"], **extra})
        if measure:
            from seatkit.body.measure import print_measurements

            print_measurements(rig)
            if out is None:
                return
        posed = model.pose(rig, load_pose(pose, frame=frame, rig=rig, dirs=registry.pose_dirs), ground=not no_ground)
        mesh = trimesh.Trimesh(posed.vertices, posed.faces, process=False)
        data = mesh.export(file_type=suffix)
        write_bytes_atomic(out, data.encode() if isinstance(data, str) else data)
        typer.echo(
            f"{out}: {len(posed.vertices)} vertices, {len(posed.faces)} triangles, "
            f"{posed.mass:.1f} kg, hip centre at y = {posed.joints[0][1]:.3f} m"
        )
        if png is not None:
            from seatkit.body.render import render_body

            render_body(posed, png, views=("front", "side"), title=posed.name, show_skeleton=True)
            typer.echo(f"{png}: preview")
