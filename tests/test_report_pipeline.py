"""The report exporters inside a real build: files in the output folder, in the run marker."""

from __future__ import annotations

import json

import pluggy

hookimpl = pluggy.HookimplMarker("seatkit")


class _ReportPlugin:
    """Registers the report exporters (until the built-in exporters plugin does)."""

    @hookimpl
    def seatkit_register_exporters(self):
        from seatkit.export.report import report_exporters

        return report_exporters()


def test_build_writes_the_report(tmp_path):
    from seatkit.pipeline import build
    from seatkit.plugins import get_plugin_manager

    pm = get_plugin_manager()
    if "report-png" not in pm.registry.names("exporter"):
        pm.register_plugin(_ReportPlugin(), "test-report")
    out = tmp_path / "out"
    result = build({"template": "flat-patch", "exporters": ["report-png", "report-html"], "output": str(out)}, pm=pm)
    names = {"pressure.png", "cage.png", "surface.png", "comparison.png", "report.html", "report.json", ".seatkit-run"}
    assert names <= {p.name for p in out.iterdir()}
    marker = json.loads((out / ".seatkit-run").read_text())
    assert {"report_html", "report_pressure_png", "report_comparison_png"} <= set(marker["files"])
    assert result.timings["export"] < 5.0
    report = json.loads((out / "report.json").read_text())
    assert report["files"]["report_html"] == "report.html"
    # the seat beside the person (seatkit.dimensions.person_fit), in report.json and report.html
    fit = report["metrics"]["person_fit"][0]
    assert fit["shoe_allowance_m"] == 0.025 and 0.3 < fit["popliteal_height_m"] < 0.6
    assert fit["seat_height_for_shoes_m"] == fit["popliteal_height_m"] + fit["shoe_allowance_m"]
    assert fit["measurements"]["buttock_popliteal_length"] == fit["buttock_popliteal_length_m"]
    html = (out / "report.html").read_text()
    assert "The seat beside person 1" in html and f"popliteal height {fit['popliteal_height_m']:.3f} m" in html
