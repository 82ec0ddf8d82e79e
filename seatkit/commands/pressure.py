"""``seatkit pressure``: the paper's pressure model on a posed body.

The body model and the pressure solver are the registered components the
build uses (``--body`` as in ``seatkit build``, ``--solver`` a registered
pressure solver, default ``qp``); ``--backend`` picks the QP backend of the
``qp`` solver (its ``backend`` option).
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from seatkit.constants import DEFAULT_BODY_MASS, DEFAULT_LAMBDA, DEFAULT_MU, GRAVITY


def register(app: typer.Typer) -> None:
    @app.command()
    def pressure(
        ctx: typer.Context,
        pose: str = typer.Option(
            "upright-sitting", "--pose", "-p", metavar="POSE",
            help="Library pose name (see 'seatkit poses'), a pose YAML file, or a .bvh file.",
        ),
        out: Path = typer.Option(..., "--out", "-o", help="Output directory (pressure.npz, pressure.ply, pressure.png)."),
        lam: float = typer.Option(
            DEFAULT_LAMBDA, "--lambda", metavar="LAMBDA",
            help="Moment/pressure balance of the paper's Eq. 4 (SI units); 'inf' = rigid body.",
        ),
        mu: float = typer.Option(DEFAULT_MU, "--mu", help="Coulomb friction coefficient."),
        solver: str = typer.Option("qp", "--solver", help="Registered pressure solver (see 'seatkit plugins'; default qp)."),
        backend: Optional[str] = typer.Option(
            None, "--backend",
            help="QP backend of the qp solver: auto (dual Newton, PIQP fallback), newton, piqp or clarabel.",
        ),
        body_name: str = typer.Option(
            "default-male", "--body", "-b", metavar="BODY",
            help="default-male, default-female, a .npz/.glb file, or MODEL:key=value,... (a registered body model).",
        ),
        mass: float = typer.Option(DEFAULT_BODY_MASS, "--mass", help="Body mass in kg."),
        exclude: Optional[str] = typer.Option(
            None, "--exclude",
            help="Comma-separated regions carrying no load (default: face,hands,abdomen; 'none' for none).",
        ),
        frame: Optional[int] = typer.Option(None, "--frame", help="BVH frame to use (for a .bvh POSE)."),
        friction: Optional[str] = typer.Option(
            None, "--friction",
            help="Friction model of the qp solver: pyramid (the paper's, default) or cone (the exact Coulomb cone, Clarabel).",
        ),
    ) -> None:
        """Solve for the reaction forces holding the body ("supported everywhere") and write them."""
        import numpy as np

        from seatkit.body import load_pose
        from seatkit.cli import plugin_manager
        from seatkit.export.pressure import write_ply, write_pressure_png
        from seatkit.pressure.compliant import friction_state
        from seatkit.pressure.field import write_npz
        from seatkit.recipe import parse_body_spec
        from seatkit.skeleton import SEGMENTS

        if exclude is None:
            names = None
        elif exclude.strip().lower() in ("", "none"):
            names = []
        else:
            names = [n.strip() for n in exclude.split(",") if n.strip()]
        registry = plugin_manager(ctx).registry
        spec = parse_body_spec(body_name)
        model = registry.get("body_model", spec["model"])
        pressure_solver = registry.get("pressure_solver", solver)
        rig = model.make_body(params={**spec["params"], "mass": mass})
        posed = model.pose(rig, load_pose(pose, frame=frame, rig=rig, dirs=registry.pose_dirs), ground=True)
        options = {"backend": backend} if backend is not None else {}
        if friction is not None:
            options["friction"] = friction
        field = pressure_solver.solve(posed, lam=lam, mu=mu, exclude=names, options=options)
        out.mkdir(parents=True, exist_ok=True)
        npz = write_npz(out / "pressure.npz", posed, field)
        ply = write_ply(out / "pressure.ply", posed, field)
        png = write_pressure_png(out / "pressure.png", posed, field, title=f"{posed.name}: relative importance (the paper's model)")
        moments = np.linalg.norm(field.joint_moment, axis=1)
        j = int(np.argmax(moments))
        limit = friction_state(field, mu=mu)
        typer.echo(
            f"{posed.name}: {field.params['n_contact']} contact vertices, total reaction "
            f"{field.force[:, 1].sum():.2f} N (weight {posed.mass * GRAVITY:.2f} N), max pressure {field.pressure.max():.0f} Pa, "
            f"max joint moment {moments[j]:.2f} N m at {SEGMENTS[j + 1]}, {field.params.get('backend', solver)} "
            f"{field.solve_seconds:.3f} s; {limit['at_limit_share']:.0%} of the loaded contacts at the friction limit "
            f"({limit['above_coulomb_share']:.0%} beyond Coulomb's cone)"
        )
        for f in (npz, ply, png):
            typer.echo(f"{f}")
