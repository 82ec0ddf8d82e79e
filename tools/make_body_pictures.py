"""The pictures of the parametric body and the percentile manikins in docs/bodies.md.

    python tools/make_body_pictures.py

writes ``docs/images/bodies/parametric-{female,male}-bmi.png`` (one stature,
BMI 15 to 45, standing), ``presets.png`` (the six manikins standing, from the front,
side by side, 0.6 m apart) and ``chairs-p5-female-p95-male.png`` (the default
chair build of both in POSE, default reclined-sitting, at the same scale, 1 m
apart: body in skin colour, the limit surface in blue; no colour bar).

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
#: Colours of the bodies and of the chairs in the chairs picture.
SKIN, CHAIR = np.array([0.85, 0.72, 0.62]), np.array([0.55, 0.68, 0.85])


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
    """p5-female's and p95-male's chairs side by side (full default builds, nothing written).

    Drawn with :mod:`seatkit.picture`: the bodies in skin colour, the limit
    surfaces in blue, both opaque, front and three-quarter, at one scale; no
    colour bar (the two colours name two things, not a scale: the title says
    which is which).
    """
    from seatkit import picture as pic
    from seatkit.io import write_bytes_atomic
    from seatkit.pipeline import build
    from seatkit.plugins import get_plugin_manager
    from seatkit.geometry.normals import vertex_normals

    pm = get_plugin_manager()
    meshes = []  # (vertices, triangles, normals, colour)
    for i, name in enumerate(("p5-female", "p95-male")):
        r = build({"template": "chair", "bodies": [{"model": name, "pose": pose}], "evaluate": {"enabled": False}}, pm=pm, write=False)
        shift = np.array([1.0 * i, 0.0, 0.0])
        body, surface = r.bodies[0], r.surface
        quads = surface.faces
        tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
        meshes.append((body.vertices + shift, body.faces, vertex_normals(body.vertices, body.faces), SKIN))
        meshes.append((surface.vertices + shift, tris, np.asarray(surface.normals, dtype=np.float64), CHAIR))
    views = {"front": (0.0, 0.0), "az 35, el 15": (35.0, 15.0)}
    frames = pic.fit_frames([m[0] for m in meshes], [pic.view_rotation(*v) for v in views.values()], 770, 620)
    panels = []
    for caption, frame in zip(views, frames):
        layers = []
        for v, f, n, rgb in meshes:
            ra = pic.rasterize(frame, v, f)
            layers.append((ra, ra.shade(pic.light_vertices(np.broadcast_to(rgb, v.shape), n, frame.rotation)), 1.0))
        panels.append((pic.to_pil(pic.composite(pic.BACKGROUND, layers)), caption))
    title = f"p5-female (left) and p95-male (right), {pose}: the default chair build (skin: the body, blue: the chair's limit surface)"
    path = OUT / "chairs-p5-female-p95-male.png"
    return write_bytes_atomic(path, pic.png_bytes(pic.sheet(title, panels)))


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
