"""Time the report exporters (report-png, report-html) on a real build.

    PYTHONPATH=. python benchmarks/bench_report.py [--template chair] [--repeat 5]

Builds the template's default recipe (with the pipeline's evaluation and
flat-patch baseline, no files written), then runs each exporter once the way
a build does (first call in the process: imports, font loading, colour
scale) and ``--repeat`` more times, printing the first call, the best and the
median, the size of each file, and the rasteriser's time per body view.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--template", default="chair")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    from seatkit.errors import SeatkitError
    from seatkit.pipeline import build

    try:
        result = build({"template": args.template}, write=False)
    except SeatkitError as exc:
        print(f"template {args.template!r} failed ({exc}); falling back to flat-patch")
        args.template = "flat-patch"
        result = build({"template": args.template}, write=False)
    body = result.bodies[0]
    print(f"template {args.template}: {len(result.bodies)} body, {len(body.vertices)} vertices, {len(body.faces)} triangles;"
          f" evaluated: {bool(result.metrics.get('ours'))}, baseline: {result.baseline is not None}")

    from seatkit.export.report import ReportHtmlExporter, ReportPngExporter

    firsts = {}
    with tempfile.TemporaryDirectory() as tmp:
        for exporter in (ReportPngExporter(), ReportHtmlExporter()):
            t0 = time.perf_counter()
            files = exporter.export(result, Path(tmp))
            first = time.perf_counter() - t0
            firsts[exporter.name] = first
            runs = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                exporter.export(result, Path(tmp))
                runs.append(time.perf_counter() - t0)
            sizes = ", ".join(f"{p.name} {p.stat().st_size / 1e6:.2f} MB" for p in files.values())
            print(f"{exporter.name:12s} first {first:.3f} s  best {min(runs):.3f} s  median {statistics.median(runs):.3f} s  ({sizes})")
    print(f"both exporters, first call: {sum(firsts.values()):.3f} s (budget 0.5 s)")

    from seatkit.picture import raster as rs

    rot = rs.view_rotation(0.0, 0.0)
    frame = rs.fit_frame([body.vertices], rot, 360, 440)
    times = []
    for _ in range(20):
        t0 = time.perf_counter()
        rs.rasterize(frame, body.vertices, body.faces, cull_back=True)
        times.append(time.perf_counter() - t0)
    print(f"rasterize one body view (360 x 440 px, {len(body.faces)} triangles): best {min(times) * 1e3:.1f} ms, median {statistics.median(times) * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
