"""``seatkit poses``: list the pose library."""

from __future__ import annotations

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def poses(ctx: typer.Context) -> None:
        """List the library poses, their description and whether the method can support them."""
        from rich.console import Console
        from rich.table import Table

        from seatkit.body import list_poses

        table = Table(box=None, show_edge=False, pad_edge=False)
        table.add_column("pose", style="bold", no_wrap=True)
        table.add_column("supported", no_wrap=True)
        table.add_column("description")
        from seatkit.cli import plugin_manager

        for info in list_poses(plugin_manager(ctx).registry.pose_dirs):
            table.add_row(info.name, "yes" if info.supported else "no", info.description)
        Console(soft_wrap=True).print(table)
