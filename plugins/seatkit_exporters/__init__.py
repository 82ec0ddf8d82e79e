"""Built-in seatkit plugin: the exporters (usd, usdc, obj, surface, shell, body-ply, design, report-png, report-html, structure, report-json)."""

from __future__ import annotations

from seatkit import hookimpl


@hookimpl
def seatkit_register_exporters():
    """Register every built-in exporter."""
    from seatkit.export.exporters import StructureExporter, builtin_exporters
    from seatkit.export.report import report_exporters
    from seatkit.export.report_json import ReportJsonExporter
    from seatkit.state import DesignExporter

    return builtin_exporters() + [DesignExporter()] + report_exporters() + [StructureExporter(), ReportJsonExporter()]
