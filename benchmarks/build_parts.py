"""CPU of the default build's parts that its processes run beside one another, each part alone.

    python benchmarks/build_parts.py [--repeat 12]
    /path/to/previous/.venv/bin/python benchmarks/build_parts.py   # the previous code, the same way

Builds the default chair once in this process (helpers off, no files), then
times, ``--repeat`` times each, the parts as a build meets them:

- the surface fit's final 5 mm check (``_final_depths``), with its level-4
  operators made (a build makes them there; its level 3 is the fit's);
- the evaluation of our design, after the fit's check and the importance
  solve on the same bodies (what the build's own process has done by then);
- the interface pressure (the soft-tissue model: a helper's, beside the
  evaluation; with nothing kept of the bodies, as in a helper forked
  before they were made);
- the report's pictures in the parts a build with helpers draws them:
  ``pressure.png`` ahead (a helper), ``surface.png`` and ``comparison.png``
  after it in the same process (the same helper), ``cage.png`` (the export
  worker), ``interface.png`` with ``pressure.png``'s bytes drawn ahead (the
  build's own process).

Prints the fastest and the median CPU time (user + system of this process,
threads included: the PNG encoding) of each. It reads a few internals
(caches it clears between runs) through ``getattr``, so that the same file
times an older checkout, whose interpreter runs it (docs/performance.md,
"One build").
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=12)
    args = ap.parse_args()
    os.environ["SEATKIT_HELPERS"] = "off"

    from seatkit.evaluate import design_segments, evaluate_design, evaluate_interface
    from seatkit.export import report
    from seatkit.geometry import surface as surface_module
    from seatkit.pipeline import build
    from seatkit.plugins import get_plugin_manager
    from seatkit.pressure.assembly import body_geometry
    from seatkit.refine import ccfit
    from seatkit.subdivision import Cage, build_operators
    from seatkit.subdivision import catmull_clark

    result = build({"template": "chair"}, write=False)
    registry = get_plugin_manager().registry
    recipe, bodies, mesh = result.recipe, result.bodies, result.control_mesh
    level = int(recipe["surface_level"])
    cage = Cage.from_control_mesh(mesh)
    pressure, ev = recipe["pressure"], recipe["evaluate"]
    solver = registry.get("pressure_solver", pressure["solver"])
    segments = design_segments(mesh)
    out = Path(tempfile.mkdtemp(prefix="build-parts-"))

    def forget_depths():
        kept = getattr(surface_module, "_BODY_DEPTHS", None)
        if kept is not None:
            kept.clear()

    def as_after_the_fit():
        # the fit's level 3 made, its level 4 not yet
        for cache in (catmull_clark._OPS_CACHE, getattr(catmull_clark, "_LEVEL_CACHE", None)):
            if cache is not None:
                cache._data.pop((cage.topology_key, 4), None)
        build_operators(cage, level)
        forget_depths()

    def as_in_the_evaluation():
        forget_depths()
        for b in bodies:
            body_geometry(b.vertices, b.faces)  # the importance map's solve
        ccfit._final_depths(mesh, bodies, level)

    def as_in_a_helper():
        # a helper is forked before the bodies exist: it keeps no areas or normals of them
        from seatkit.geometry import normals
        from seatkit.pressure import assembly

        for module, name in ((normals, "_KEPT"), (assembly, "_AREAS"), (assembly, "_GEOMETRY")):
            kept = getattr(module, name, None)
            if kept is not None:
                kept.clear()

    def forget_rasters():
        kept = getattr(report, "_BODY_RASTERS", None)
        if kept is not None:
            kept.clear()

    def after_pressure_png():
        forget_rasters()
        report.draw_early_pngs(result)

    early = report.draw_early_pngs(result)
    parts = {
        "surface fit's final check (level 4 made)": (as_after_the_fit, lambda: ccfit._final_depths(mesh, bodies, level)),
        "evaluation of our design": (
            as_in_the_evaluation,
            lambda: evaluate_design(
                bodies, result.pressures, result.surface, solver=solver, support_distance=ev["support_distance"], pressure_settings=pressure, segments=segments
            ),
        ),
        "interface pressure (in a helper)": (as_in_a_helper, lambda: evaluate_interface(bodies, result.surface, mu=pressure.get("mu"))),
        "pressure.png, drawn ahead": (forget_rasters, lambda: report.draw_early_pngs(result)),
        "surface.png + comparison.png, after it": (
            after_pressure_png,
            lambda: report.render_pngs(result, out, roles=("report_surface_png", "report_comparison_png")),
        ),
        "cage.png": (forget_rasters, lambda: report.render_pngs(result, out, roles=("report_cage_png",))),
        "interface.png (pressure.png's bytes ahead)": (
            forget_rasters,
            lambda: report.render_pngs(result, out, roles=("report_pressure_png", "report_interface_png"), early=early),
        ),
    }
    print(f"{'part':46s} {'fastest':>9s} {'median':>9s}   (CPU, {args.repeat} runs)")
    for name, (setup, run) in parts.items():
        setup()
        run()  # warm: imports, first-use tables
        times = []
        for _ in range(args.repeat):
            setup()
            t0 = time.process_time()
            run()
            times.append(time.process_time() - t0)
        print(f"{name:46s} {min(times) * 1000:7.1f} ms {statistics.median(times) * 1000:7.1f} ms")


if __name__ == "__main__":
    main()
