"""What the surface fit's guarded refit spends on its inside test, and what re-testing only the body vertices the surface may have reached could save.

For each drawn pose (``FAMILY-INDEX@BODY``, draw seed 2026, as the
generalisation benchmark draws them) it runs the default build (seed 0) up
to its first guarded refit (:func:`seatkit.refine.ccfit._fit_cage`), then
runs that refit alone on one BLAS thread, as a build does, timing every
call of the inside test (:func:`seatkit.geometry.surface.inside_furniture`,
every guarded body vertex, every iteration).

A vertex can only go in or out of the furniture when the surface passes
through it, and no point of the tessellation moves farther in an iteration
than its farthest-moving vertex. So an incremental test would re-test a
vertex only once the surface's moves since its last test add up to its
distance to the surface. The benchmark replays the refit's surfaces with
every vertex's distance to each (the closest-point query's, within 0.1 mm,
taken as free, which no real test's is) and counts the vertices such a test would re-test: the CPU it could save is
at most the inside test's CPU times the share it would skip.
docs/performance.md, "The guarded refit's inside test", gives what it measured:

    python benchmarks/bench_guard.py seated-008@default-male seated-156@default-female
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


class _Captured(Exception):
    """The first guarded refit's inputs (stops the build there)."""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", nargs="+", help="FAMILY-INDEX@BODY, e.g. seated-008@default-male")
    args = ap.parse_args()

    from threadpoolctl import threadpool_limits

    from seatkit.body.generator import draw_case, pose_yaml
    from seatkit.errors import SeatkitError
    from seatkit.geometry.closest import row_norms
    from seatkit.geometry.surface import SurfaceQuery
    from seatkit.pipeline import build
    from seatkit.refine import ccfit

    fit_once, inside_furniture = ccfit._fit_once, ccfit.inside_furniture
    captured: list = []

    def capture(mesh, bodies, pressures, params, *, guard=False, **kw):
        if guard:
            captured.append((mesh, bodies, pressures, params, kw))
            raise _Captured
        return fit_once(mesh, bodies, pressures, params, guard=guard, **kw)

    calls: list = []

    def timed(surface, points, **kw):
        start = time.process_time()
        out = inside_furniture(surface, points, **kw)
        calls.append((time.process_time() - start, surface, points))
        return out

    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            drawn, body = draw_case(case)
            path = Path(tmp) / f"{drawn.name}.yaml"
            path.write_text(pose_yaml(drawn))
            captured.clear()
            ccfit._fit_once = capture
            try:
                build({"template": "chair", "seed": 0, "bodies": [{"model": body, "pose": str(path)}]}, write=False, processes=False)
            except SeatkitError:
                pass
            finally:
                ccfit._fit_once = fit_once
            if not captured:
                print(f"{case}: no guarded refit", flush=True)
                continue
            mesh, bodies, pressures, params, kw = captured[0]
            with threadpool_limits(limits=1):
                start = time.process_time()
                out = fit_once(mesh, bodies, pressures, params, guard=True, **kw)
                refit = time.process_time() - start
                calls.clear()
                ccfit.inside_furniture = timed
                try:
                    fit_once(mesh, bodies, pressures, params, guard=True, **kw)
                finally:
                    ccfit.inside_furniture = inside_furniture
            tests = list(calls)  # (the refit calls it for its guarded vertices only)
            points = tests[0][2]
            # replay: each vertex re-tested once the surface's largest moves since its test add up to its distance
            margin = np.full(len(points), -np.inf)
            retested, moves, previous = [], [], None
            distance_cpu, asked = 0.0, 0
            for _, surface, _ in tests:
                X = np.asarray(surface.vertices)
                if previous is not None:
                    moves.append(float(row_norms(X - previous).max()))
                    margin -= moves[-1]
                stale = margin <= 0.0
                if previous is not None:
                    retested.append(float(stale.mean()))
                start = time.process_time()
                margin[stale] = SurfaceQuery(surface).query(points[stale])[0]
                distance_cpu += time.process_time() - start
                asked += int(stale.sum())
                previous = X
            parity = sum(cpu for cpu, _, _ in tests)
            share = float(np.mean(retested)) if retested else 1.0
            print(
                f"{case}: guarded refit {refit:.2f} s CPU, {out.meta['catmull-clark-fit']['iterations']} iterations, "
                f"{len(points)} guarded vertices; inside test {parity:.2f} s ({len(tests)} calls, "
                f"{1000 * parity / len(tests):.1f} ms each); the surface's largest move an iteration "
                f"{1000 * np.median(moves):.1f} mm (median), {1000 * max(moves):.1f} mm (largest); "
                f"re-tested with free distances: {100 * share:.0f}% a call; could save at most "
                f"{parity * (1 - share) * (len(tests) - 1) / len(tests):.2f} s ({100 * parity * (1 - share) / refit:.0f}% of the refit); "
                f"per vertex: inside test {1e6 * parity / (len(tests) * len(points)):.2f} us, "
                f"the distances (SurfaceQuery) {1e6 * distance_cpu / max(asked, 1):.2f} us",
                flush=True,
            )


if __name__ == "__main__":
    main()
