"""The pictures of the parametric body and the percentile manikins in docs/bodies.md.

    python tools/make_body_pictures.py

writes ``docs/images/bodies/parametric-{female,male}-bmi.png`` (one stature,
BMI 15 to 45, standing), ``presets.png`` (the six manikins standing, from the front,
side by side, 0.6 m apart) and ``chairs-p5-female-p95-male.png`` (the default
chair build of both in POSE, default reclined-sitting, at the same scale, 1 m
apart: body in skin colour, the limit surface in blue).

    python tools/make_body_pictures.py [--pose reclined-sitting]
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


def chairs(pose: str) -> Path:
    """p5-female's and p95-male's chairs side by side (full default builds, nothing written)."""
    from seatkit.pipeline import build
    from seatkit.plugins import get_plugin_manager

    pm = get_plugin_manager()
    vertices, faces, colour, offset = [], [], [], 0
    for i, name in enumerate(("p5-female", "p95-male")):
        r = build({"template": "chair", "bodies": [{"model": name, "pose": pose}], "evaluate": {"enabled": False}}, pm=pm, write=False)
        quads = r.surface.faces
        tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
        for v, f, c in ((r.bodies[0].vertices, r.bodies[0].faces, 0.0), (r.surface.vertices, tris, 1.0)):
            v = v + np.array([1.0 * i, 0.0, 0.0])
            vertices.append(v)
            faces.append(f + offset)
            colour.append(np.full(len(v), c))
            offset += len(v)
    path = OUT / "chairs-p5-female-p95-male.png"
    mesh = SimpleNamespace(vertices=np.concatenate(vertices), faces=np.concatenate(faces))
    from matplotlib.colors import ListedColormap

    cmap = ListedColormap([(0.85, 0.72, 0.62), (0.55, 0.68, 0.85)])
    render_body(mesh, path, scalars=np.concatenate(colour), cmap=cmap, clim=(0.0, 1.0), views=("front", (35.0, 15.0)),
                scalar_label="0 body, 1 chair",
                title=f"p5-female (left) and p95-male (right), {pose}: the default chair build", panel_size=7)
    return path


def main() -> None:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pose", default="reclined-sitting")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    for sex in ("female", "male"):
        rigs = [make_parametric_body(sex, stature=1.70, mass=b * 1.70**2) for b in BMIS]
        path = OUT / f"parametric-{sex}-bmi.png"
        render_body(lineup(rigs, "standing", 0.6), path, views=("front",), title=f"{sex}, 1.70 m, BMI {', '.join(map(str, BMIS))}", panel_size=9)
        print(path)
    path = OUT / "presets.png"
    render_body(lineup([make_preset(n) for n in PRESETS], "standing", 0.6), path, views=("front",), title=", ".join(PRESETS), panel_size=9)
    print(path)
    print(chairs(args.pose))


if __name__ == "__main__":
    main()
