"""Built-in seatkit plugin: the exporters (usd, usdc, obj, surface, shell, body-ply)."""

from __future__ import annotations

import pluggy

hookimpl = pluggy.HookimplMarker("seatkit")


@hookimpl
def seatkit_register_exporters():
    """Register every built-in exporter."""
    from seatkit.export.exporters import builtin_exporters

    return builtin_exporters()
