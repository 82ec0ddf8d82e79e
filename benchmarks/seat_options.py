"""The seat step's options over every preset body and supported library pose: is the built design's dimension the one set?

For each body and pose, a chair with the seat 8 cm above where the pose puts
it (``seat.height``), with a backrest 0.65 m above the seat point
(``seat.backrest_height``), or with a seat that ends 8 cm short of the nearer
knee joint (``seat.depth``, the front edge clear of the back of the knee),
or with the backrest reclined 15 deg behind vertical (``seat.recline``, a
105 deg seat-to-back angle on a level seat);
prints one JSON line per design: the value set, the one measured on the
built surface (the surface under the seat point; the surface's highest point
behind it, above the seat point; the front edge from the back of the
buttocks along the thighs; the backrest's recline), the evaluation's two 5 mm
figures (for the
depth also the largest contact pressure on the thigh more than 1 cm ahead of
the front edge), or the refusal and its one line; then the counts.

    python benchmarks/seat_options.py seat|backrest|depth|recline [--bodies default-female ...] [--poses upright-sitting ...] [--images DIR]

``--images DIR`` draws each built design (its cage, surface and body from
the front, the side and three-quarter) to ``DIR/OPTION-BODY-POSE.png``.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter

BODIES = ["default-female", "default-male", "p5-female", "p50-male", "p95-female", "p95-male"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("option", choices=["seat", "backrest", "depth", "recline"])
    ap.add_argument("--bodies", nargs="+", default=BODIES, help="preset bodies (default: six)")
    ap.add_argument("--poses", nargs="+", default=None, help="library poses (default: every supported one)")
    ap.add_argument("--images", default=None, help="draw each built design into this folder")
    args = ap.parse_args()
    from seatkit.body import list_poses
    from seatkit.errors import SeatkitError
    from seatkit.pipeline import build
    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import load_recipe
    from seatkit.stages import place_bodies
    from seatkit.template.seat import backrest_top, built_recline, depth_range, seat_axis, seat_depth_of, seat_height_of, seat_point, surface_below

    registry = get_plugin_manager().registry
    poses = args.poses or [p.name for p in list_poses() if p.supported]
    outcome: Counter = Counter()
    for body in args.bodies:
        for pose in poses:
            recipe, _ = load_recipe({"template": "chair", "bodies": [{"model": body, "pose": pose}], "evaluate": {"baseline": None}})
            recipe["output"] = None
            start = time.perf_counter()
            row = {"body": body, "pose": pose}
            try:
                if args.option == "seat":
                    value = round(float(seat_point(place_bodies(recipe, registry)[0][0])[1]) + 0.08, 3)
                    recipe["template_params"] = {"steps": {"seat": {"height": value}}}
                elif args.option == "recline":
                    value = 15.0
                    recipe["template_params"] = {"steps": {"seat": {"recline": value}}}
                elif args.option == "depth":
                    value = round(depth_range(place_bodies(recipe, registry)[0][0])[1] - 0.08, 3)
                    recipe["template_params"] = {"steps": {"seat": {"depth": value}}}
                else:
                    value = 0.65
                    recipe["template_params"] = {"steps": {"seat": {"backrest_height": value}}}
                result = build(recipe, write=False, processes=False)
                if args.option == "seat":
                    got = surface_below(result.surface.vertices, result.surface.faces, seat_point(result.bodies[0]), reach=0.1)
                elif args.option == "recline":
                    got = built_recline(result.surface, result.bodies)
                elif args.option == "depth":
                    got = seat_depth_of(result.control_mesh, result.bodies)[0]
                    row["thigh_ahead_max_pa"] = round(thigh_pressure_ahead(result, seat_axis, value + 0.01), 1)
                else:
                    seat_y, seat_z = seat_height_of(result.bodies)
                    got = backrest_top(result.surface.vertices, seat_z) - seat_y
                ours = result.metrics["ours"][0]
                tolerance = 2.0 if args.option == "recline" else 0.005
                within = abs(got - value) <= tolerance and max(ours["max_penetration_m"], ours["max_body_depth_m"]) <= 0.005
                outcome["within tolerance, the 5 mm limits kept" if within else "built, not within tolerance"] += 1
                if args.images:
                    from pathlib import Path

                    from seatkit.template.render import render_cage

                    Path(args.images).mkdir(parents=True, exist_ok=True)
                    unit = "deg" if args.option == "recline" else "m"
                    render_cage(result.control_mesh, result.bodies, Path(args.images) / f"{args.option}-{body}-{pose}.png", title=f"chair: {pose}, {body}, {args.option} {value:g} {unit} (built {got:.3g})")
                row.update(set=value, got=round(got, 4), penetration_mm=round(1000 * ours["max_penetration_m"], 1), body_depth_mm=round(1000 * ours["max_body_depth_m"], 1), back_height_m=result.metrics["dimensions"][0]["back_height_m"])
            except SeatkitError as e:
                outcome[f"refused ({type(e).__name__})"] += 1
                row.update(refused=type(e).__name__, message=str(e))
            row["seconds"] = round(time.perf_counter() - start, 1)
            print(json.dumps(row), flush=True)
    print(json.dumps(dict(outcome)))


def thigh_pressure_ahead(result, seat_axis, depth: float) -> float:
    """The largest contact pressure the built design puts on thigh skin more than ``depth`` from the back of the buttocks along the thighs, Pa (0 when none is carried there)."""
    import numpy as np

    from seatkit.skeleton import SEGMENT_INDEX
    from seatkit.template.grid import segment_of_vertex

    body = result.bodies[0]
    field = result.contact_pressures[0] if result.contact_pressures else None
    if field is None:
        return float("nan")
    s, back = seat_axis(body)
    thighs = np.isin(segment_of_vertex(body), [SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]])
    ahead = thighs & ((np.asarray(body.vertices) - back) @ s > depth)
    p = np.asarray(field.pressure)[ahead]
    return float(p.max()) if len(p) else 0.0


if __name__ == "__main__":
    main()
