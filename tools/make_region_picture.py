"""The picture of the default bodies' named vertex regions in docs/poses.md.

    python tools/make_region_picture.py

writes ``docs/images/poses/regions.png``: the default male body in its rest
pose from the front, the side and below, each region (``face``, ``hands``,
``forearms``, ``abdomen``, ``feet_soles``: the pressure solver's default
exclusions, docs/pressure.md) in its own colour, named in a legend; the
rest of the skin in skin colour.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from seatkit.body import load_rig
from seatkit.body.render import render_body

OUT = Path(__file__).resolve().parent.parent / "docs" / "images" / "poses" / "regions.png"
SKIN = (0.85, 0.72, 0.62)
#: One colour per region, far apart from each other and from the skin.
COLOURS = {
    "face": (0.12, 0.47, 0.71),
    "hands": (1.00, 0.50, 0.05),
    "forearms": (0.17, 0.63, 0.17),
    "abdomen": (0.84, 0.15, 0.16),
    "feet_soles": (0.58, 0.40, 0.74),
}


def main() -> None:
    rig = load_rig("default-male")
    colours = np.tile(SKIN, (len(rig.vertices), 1))
    missing = sorted(set(rig.region_labels) - set(COLOURS))
    if missing:
        raise SystemExit(f"regions without a colour: {', '.join(missing)}")
    for name, idx in rig.region_labels.items():
        colours[idx] = COLOURS[name]
    entries = [(name, COLOURS[name]) for name in rig.region_labels] + [("other skin", SKIN)]
    render_body(rig, OUT, colors=colours, legend=entries, scalar_label="region", views=("front", "side", "bottom"),
                title="default-male: the named vertex regions (the pressure solver's default exclusions)")
    print(OUT)


if __name__ == "__main__":
    main()
