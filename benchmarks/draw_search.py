"""The design search on one drawn pose, drawn: a rejected candidate beside the design.

Poses a draw of ``seatkit.body.generator`` (draw seed 2026, as the
generalisation benchmark), runs the stages of a build up to the design
search (``seatkit.search``) and draws, side by side, the first rejected
candidate's fitted surface and the design the search accepted, each with
the body: an orange dot where the limit surface lies more than ``--limit`` (5 mm)
inside the body, a red dot where a body vertex lies more than 5 mm inside the
furniture (the solid the surface closes with the floor). The title of each
panel gives the candidate's origin, its template start and the two depths.
Prints every candidate's verdict, in order.

    python benchmarks/draw_search.py reclined 49 --body default-male --out search.png

With ``--first-cage`` it draws the template's first cage instead (its
cage, not a fitted surface: ``seatkit.template.render.render_cage``), as a
build's ``cage.png`` shows it.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

#: Colours (RGB in [0, 1]): body, surface, the surface in the body, the body in the furniture.
BODY, SURFACE, SURFACE_DEEP, BODY_DEEP = (0.86, 0.72, 0.60), (0.55, 0.62, 0.72), (1.0, 0.55, 0.0), (0.85, 0.05, 0.05)
#: Opacities: both translucent, so that a spot of one inside the other shows through.
BODY_ALPHA, SURFACE_ALPHA = 0.7, 0.6
#: Radius of the dots on the spots over the limit, pixels.
DOT = 2.5


def drawn_recipe(family: str, index: int, body: str, seed: int, draw_seed: int, folder: Path) -> dict:
    """The recipe of one drawn pose on one body, its pose written as the generalisation benchmark writes it."""
    from seatkit.body.generator import draw_pose, pose_yaml

    drawn = draw_pose(np.random.default_rng([draw_seed, index]), family, f"{family}-{index:03d}")
    path = folder / f"{drawn.name}.yaml"
    path.write_text(pose_yaml(drawn))
    return {"template": "chair", "seed": seed, "bodies": [{"model": body, "pose": str(path)}]}


def run_search(recipe: dict):
    """The build's stages up to the design search: ``(bodies, outcome, first cage)``; a template that refuses the pose raises."""
    import itertools

    from seatkit.plugins import get_plugin_manager
    from seatkit.recipe import check_recipe, load_recipe
    from seatkit.search import bind, search, template_cages
    from seatkit.stages import place_bodies, refine, solve_importance

    registry = get_plugin_manager().registry
    data, document = load_recipe(recipe)
    recipe = check_recipe(data, registry, document=document)
    bodies, _ = place_bodies(recipe, registry)
    pressures = solve_importance(recipe, bodies, registry)
    template = registry.get("template", recipe["template"])
    cages = template_cages(template, bodies, pressures, params=recipe["template_params"], seed=recipe["seed"])
    first = next(cages)
    refiners = [(r["name"], registry.guarded("refiner", r["name"], template=template), r["params"]) for r in recipe["refiners"]]
    sources = bind(template, bodies, pressures, params=recipe["template_params"], seed=recipe["seed"], first=itertools.chain([first], cages))
    fit_last = bool(refiners) and refiners[-1][0] == "catmull-clark-fit"
    outcome = search(sources, lambda cage: refine(cage, refiners, bodies, pressures), bodies, fit_last=fit_last)
    return bodies, outcome, first


def deep_spots(surface, bodies, limit: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """Surface vertices more than ``limit`` inside a body, and each body's vertices more than ``limit`` inside the furniture."""
    from seatkit.geometry.skin import SkinDistance
    from seatkit.geometry.surface import SurfaceQuery, inside_furniture

    in_body = np.zeros(len(surface.vertices), bool)
    for b in bodies:
        depth, _, _ = SkinDistance.of(b.vertices, b.faces).query(surface.vertices)
        in_body |= depth > limit
    in_surface = []
    query = SurfaceQuery(surface)
    for b in bodies:
        inside = np.flatnonzero(inside_furniture(surface, b.vertices))
        deep = np.zeros(len(b.vertices), bool)
        if inside.size:
            dist, _ = query.query(b.vertices[inside])
            deep[inside[dist > limit]] = True
        in_surface.append(deep)
    return in_body, in_surface


def panel(surface, bodies, frame, limit: float):
    """One view: the body and the limit surface, translucent, and a dot on every spot over ``limit`` (drawn on top: they are inside)."""
    from PIL import ImageDraw

    from seatkit import picture as pic
    from seatkit.geometry.normals import vertex_normals

    in_body, in_surface = deep_spots(surface, bodies, limit)
    layers = []
    for b in bodies:
        r = pic.rasterize(frame, b.vertices, b.faces)
        layers.append((r, r.shade(pic.light_vertices(np.broadcast_to(BODY, b.vertices.shape), vertex_normals(b.vertices, b.faces), frame.rotation)), BODY_ALPHA))
    quads = np.asarray(surface.faces)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    r = pic.rasterize(frame, surface.vertices, tris)
    layers.append((r, r.shade(pic.light_vertices(np.broadcast_to(SURFACE, surface.vertices.shape), np.asarray(surface.normals), frame.rotation)), SURFACE_ALPHA))
    image = pic.to_pil(pic.composite(pic.BACKGROUND, layers))
    draw = ImageDraw.Draw(image)
    spots = [(surface.vertices[in_body], SURFACE_DEEP)] + [(b.vertices[deep], BODY_DEEP) for b, deep in zip(bodies, in_surface)]
    for points, colour in spots:
        rgb = tuple(int(round(255 * c)) for c in colour)
        for x, y in frame.project(points)[0]:
            draw.ellipse((x - DOT, y - DOT, x + DOT, y + DOT), fill=rgb)
    return image


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family", help="a pose family of seatkit.body.generator (seated, reclined, ...)")
    ap.add_argument("index", type=int, help="the draw's index (the benchmark's pose number)")
    ap.add_argument("--body", default="default-female")
    ap.add_argument("--seed", type=int, default=0, help="the build's seed")
    ap.add_argument("--draw-seed", type=int, default=2026)
    ap.add_argument("--views", nargs="+", default=["side", "three-quarter"], help="views of seatkit.template.render.VIEWS")
    ap.add_argument("--limit", type=float, default=0.005, help="depth drawn as over the limit, m")
    ap.add_argument("--first-cage", action="store_true", help="draw the template's first cage instead")
    ap.add_argument("--title", default="", help="what the picture shows (after the pose's name)")
    ap.add_argument("--out", default="search.png")
    args = ap.parse_args()

    from threadpoolctl import threadpool_limits

    from seatkit import picture as pic
    from seatkit.io import write_bytes_atomic
    from seatkit.refine.ccfit import final_depths
    from seatkit.subdivision import limit_surface
    from seatkit.template.render import VIEWS, render_cage

    name = f"{args.family}-{args.index:03d}, {args.body}, seed {args.seed}"
    with tempfile.TemporaryDirectory() as folder, threadpool_limits(limits=1):
        recipe = drawn_recipe(args.family, args.index, args.body, args.seed, args.draw_seed, Path(folder))
        bodies, outcome, first = run_search(recipe)
    if args.first_cage:
        render_cage(first, bodies, args.out, views=args.views, title=f"{name}: {args.title or 'the first cage'}")
        print(f"wrote {args.out}")
        return
    for i, t in enumerate(outcome.tried, 1):
        verdict = "accepted" if t.verdict.accepted else f"rejected: {t.verdict.reason}"
        print(f"{i}. {t.candidate.origin.value} (start {t.candidate.start}): {verdict}")
    rejected = next((t for t in outcome.tried if not t.verdict.accepted and t.refined is not None), None)
    shown = ([(rejected, "rejected")] if rejected is not None else []) + ([(outcome.tried[outcome.winner], "the design")] if outcome.winner is not None else [])
    if not shown:
        raise SystemExit(f"{name}: no candidate was fitted")
    surfaces = [limit_surface(t.refined, level=3) for t, _ in shown]
    points = [s.vertices for s in surfaces] + [b.vertices for b in bodies]
    width, height = 380, 400
    frames = pic.fit_frames([np.concatenate(points)], [pic.view_rotation(*VIEWS[v]) for v in args.views], width, height)
    legend = f"orange, the surface more than {args.limit * 1000:g} mm in the body; red, the body more than {args.limit * 1000:g} mm inside the furniture"
    panels, lines = [], [f"{name}: {args.title}", legend] if args.title else [f"{name}: {legend}"]
    for (t, label), surface in zip(shown, surfaces):
        depths = final_depths(t.refined, bodies)
        lines.append(f"{label}: {t.candidate.origin.value} candidate, template start {t.candidate.start}: the surface {depths['surface_in_body'] * 1000:.1f} mm in the body, the body {depths['body_in_surface'] * 1000:.1f} mm inside the furniture")
        for view, frame in zip(args.views, frames):
            image = panel(surface, bodies, frame, args.limit)
            panels.append((image, f"{label} ({view})"))
    sheet = pic.sheet("\n".join(lines), panels)
    write_bytes_atomic(Path(args.out), pic.png_bytes(sheet))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
