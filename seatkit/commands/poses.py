"""``seatkit poses``: list the pose library, or check whether a template can support a pose."""

from __future__ import annotations

from typing import Optional

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def poses(
        ctx: typer.Context,
        check: Optional[str] = typer.Option(
            None, "--check", metavar="POSE_OR_FILE",
            help="Say whether the template can support this pose (library name, pose YAML or .bvh) and why not; exit code 1 when it cannot.",
        ),
        body_name: str = typer.Option("default-male", "--body", "-b", metavar="NAME|PATH", help="Body the pose is checked on (with --check)."),
        template_name: str = typer.Option("chair", "--template", "-t", help="Template whose pose rule applies (with --check)."),
        frame: Optional[int] = typer.Option(None, "--frame", help="BVH frame (with --check and a .bvh POSE)."),
    ) -> None:
        """List the library poses, their description and whether the method can support them."""
        from rich.console import Console
        from rich.table import Table

        from seatkit.body import list_poses

        if check is not None:
            _check(ctx, check, body_name, template_name, frame)
            return
        table = Table(box=None, show_edge=False, pad_edge=False)
        table.add_column("pose", style="bold", no_wrap=True)
        table.add_column("supported", no_wrap=True)
        table.add_column("description")
        from seatkit.cli import plugin_manager

        for info in list_poses(plugin_manager(ctx).registry.pose_dirs):
            table.add_row(info.name, "yes" if info.supported else "no", info.description)
        Console(soft_wrap=True).print(table)


def _check(ctx, pose: str, body_name: str, template_name: str, frame) -> None:
    from seatkit.body import load_pose
    from seatkit.body.frame import to_canonical
    from seatkit.cli import plugin_manager
    from seatkit.recipe import parse_body_spec
    from seatkit.template.pose_rule import assess_pose, template_rule

    registry = plugin_manager(ctx).registry
    template = registry.get("template", template_name)
    spec = parse_body_spec(body_name)
    model = registry.get("body_model", spec["model"])
    rig = model.make_body(params=dict(spec["params"]))
    # judged where the build judges it: in the canonical frame (seatkit.body.frame)
    posed = to_canonical(model.pose(rig, load_pose(pose, frame=frame, rig=rig, dirs=registry.pose_dirs), ground=True))[0]
    rule = template_rule(template)
    if rule is None:
        typer.echo(f"{pose}: template {template_name!r} declares no pose rule; only a build can tell (seatkit build --pose {pose})")
        return
    verdict = assess_pose(posed, rule)
    if verdict.supportable:
        typer.echo(f"{pose}: supportable by the {template_name} template (on {posed.name.split(':')[0] or body_name})")
        return
    typer.echo(f"{pose}: not supportable by the {template_name} template:")
    for reason in verdict.reasons:
        typer.echo(f"  - {reason}")
    raise typer.Exit(1)
