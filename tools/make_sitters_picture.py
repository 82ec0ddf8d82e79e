"""The picture of docs/sitters.md: one seat and each of its sitters on it.

    python tools/make_sitters_picture.py [RECIPE] [--out PNG]

Builds the recipe (default ``examples/recipes/sitters.yaml``, nothing
written but the picture) and draws, for each sitter, the shared limit
surface with that sitter alone over it (side and three-quarter views), the
sitter coloured by the contact pressure on the shared surface, one colour
scale for all; under it each sitter's Table 1 on the shared design, on the
flat patch and on the sitter's own design.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recipe", nargs="?", default=str(ROOT / "examples" / "recipes" / "sitters.yaml"))
    parser.add_argument("--out", default=str(ROOT / "docs" / "images" / "sitters" / "three-sitters.png"))
    args = parser.parse_args()

    import numpy as np

    from seatkit.export import report as rp
    from seatkit.picture import raster as rs
    from seatkit.pipeline import build

    result = build(args.recipe, write=False, processes=False)
    scenes = [
        rp._scene(replace(result, bodies=[b], pressures=[p], contact_pressures=[c], baseline=None))
        for b, p, c in zip(result.bodies, result.pressures, result.contact_pressures)
    ]
    vmax = rp.contact_scale(*[c.pressure for c in result.contact_pressures if c is not None])
    panels = []
    for scene, label in zip(scenes, rp.person_labels(result.bodies)):
        for view in ("side", "three-quarter"):
            # every sitter in the same frame: the frame of the whole shared scene
            scene._frames[(view, "scene")] = rs.fit_frame(
                [np.concatenate([b.vertices for b in result.bodies]), scene.surface.vertices], rs.view_rotation(*rp.VIEWS[view]), rp.PANEL_WIDTH, rp.PANEL_HEIGHT
            )
            layers = [rp._body_layer(scene, view, "scene", scene.contact, vmax), scene.layer("surface", view, "scene", rp.SURFACE_RGB, rp.SURFACE_ALPHA)]
            panels.append((rp._pil(rs.composite(rp.BACKGROUND, layers)), f"{label}: {view}"))
    title = f"One seat, {len(scenes)} sitters: each on the shared surface; contact pressure (paper's model) up to {vmax / 1000:.1f} kPa"
    sheet = rp._sheet(
        title, panels, colorbar=rp._colorbar(rp.PANEL_HEIGHT, vmax, "kPa"), table=rp.table_rows(result.metrics, rp.person_labels(result.bodies), own=True),
        table_head=rp._table_head(result.metrics, str(result.metrics.get("baseline_template"))), columns=2,
    )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
