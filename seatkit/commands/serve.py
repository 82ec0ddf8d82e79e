"""``seatkit serve``: the web app (seatkit/serve/) on uvicorn."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

#: The address the app listens on unless --host says otherwise: this machine only.
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765


def register(app: typer.Typer) -> None:
    @app.command()
    def serve(
        ctx: typer.Context,
        host: str = typer.Option(DEFAULT_HOST, "--host", help="Address to listen on (default this machine only)."),
        port: int = typer.Option(DEFAULT_PORT, "--port", help="Port to listen on."),
        no_browser: bool = typer.Option(False, "--no-browser", help="Do not open the page in a browser."),
        folder: Optional[Path] = typer.Option(
            None, "--folder", help="Where designs, uploads and files go (default seatkit-out/serve)."
        ),
    ) -> None:
        """Design a chair interactively in the browser: pose sliders, body, template, live 3D view, downloads."""
        import threading
        import webbrowser

        from seatkit.cli import plugin_manager, stderr_console
        from seatkit.errors import MissingExtraError, SeatkitError

        try:
            import starlette  # noqa: F401
            import uvicorn
        except ImportError as e:
            raise MissingExtraError(e.name or "starlette", "serve") from None
        from seatkit.serve.app import create_app
        from seatkit.serve.designer import Designer

        if not 0 < port < 65536:
            raise SeatkitError(f"--port: expected a port number between 1 and 65535, got {port}")
        if host not in ("127.0.0.1", "localhost", "::1"):
            typer.echo(
                f"seatkit: warning: listening on {host}: anyone who can reach this address can run designs "
                "and read the designs' files; the app has no login",
                err=True,
            )
        from seatkit.side import use_side_thread

        designer = Designer(folder or Path("seatkit-out") / "serve", pm=plugin_manager(ctx))
        # one design at a time, alone on the machine: the surface fit's
        # independent queries run side by side (seatkit.side)
        use_side_thread(True)
        url = f"http://{'localhost' if host in ('0.0.0.0', '::') else host}:{port}/"
        console = stderr_console()
        console.print(f"seatkit serve: [bold]{url}[/]  (files in {designer.root}; Ctrl+C to stop)")
        config = uvicorn.Config(create_app(designer), host=host, port=port, log_level="warning", lifespan="off")
        server = uvicorn.Server(config)
        if not no_browser:
            def _open() -> None:
                import time

                while not server.started and not server.should_exit:
                    time.sleep(0.05)
                if server.started:
                    webbrowser.open(url)

            threading.Thread(target=_open, daemon=True).start()
        try:
            server.run()
        except SystemExit:  # uvicorn leaves with sys.exit when it cannot bind
            server.started = False
        if not server.started:
            raise SeatkitError(f"could not listen on {host}:{port} (is the port in use? try --port)")
