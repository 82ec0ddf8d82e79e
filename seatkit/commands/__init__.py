"""CLI subcommands, one module each.

Every module here defines ``register(app: typer.Typer) -> None`` adding its
command(s); :mod:`seatkit.cli` imports them all in name order. Keep module
imports light: import heavy libraries inside the command functions so that
``seatkit --help`` stays fast.
"""
