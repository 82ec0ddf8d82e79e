"""The pictures of the parametric body and the percentile manikins in docs/bodies.md.

    python tools/make_body_pictures.py

writes ``docs/images/bodies/parametric-{female,male}-bmi.png`` (one stature,
BMI 15 to 45, standing) and ``presets.png`` (the six manikins standing, from the front,
side by side, 0.6 m apart).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from seatkit.body import load_pose, pose_rig
from seatkit.body.parametric import make_parametric_body
from seatkit.body.presets import PRESETS, make_preset
from seatkit.body.render import render_body

OUT = Path(__file__).resolve().parent.parent / "docs" / "images" / "bodies"
BMIS = (15, 19, 23, 27, 32, 38, 45)


def lineup(rigs, pose: str, gap: float) -> SimpleNamespace:
    """One mesh of the posed bodies, side by side along x."""
    vertices, faces, offset = [], [], 0
    for i, rig in enumerate(rigs):
        body = pose_rig(rig, load_pose(pose))
        v = body.vertices.copy()
        v[:, 0] += i * gap
        vertices.append(v)
        faces.append(body.faces + offset)
        offset += len(v)
    return SimpleNamespace(vertices=np.concatenate(vertices), faces=np.concatenate(faces))


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for sex in ("female", "male"):
        rigs = [make_parametric_body(sex, stature=1.70, mass=b * 1.70**2) for b in BMIS]
        path = OUT / f"parametric-{sex}-bmi.png"
        render_body(lineup(rigs, "standing", 0.6), path, views=("front",), title=f"{sex}, 1.70 m, BMI {', '.join(map(str, BMIS))}", panel_size=9)
        print(path)
    path = OUT / "presets.png"
    render_body(lineup([make_preset(n) for n in PRESETS], "standing", 0.6), path, views=("front",), title=", ".join(PRESETS), panel_size=9)
    print(path)


if __name__ == "__main__":
    main()
