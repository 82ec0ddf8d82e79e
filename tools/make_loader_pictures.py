"""The glTF pictures in docs/bodies.md ("glTF / GLB skinned bodies").

    python tools/make_loader_pictures.py [--pose leaning-forward]

writes ``docs/images/bodies/gltf-default-female.png`` (default-female
written as a GLB with ``save_gltf_body``, read back with ``load_gltf_body``,
each vertex coloured by the segment that weighs most on it, the segments
named in a legend, the skeleton on top) and ``gltf-posed.png`` (the body
read back, posed in POSE, with its skeleton).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from seatkit.body import load_pose, load_rig, pose_rig
from seatkit.body.gltf import load_gltf_body, save_gltf_body
from seatkit.body.render import render_body
from seatkit.skeleton import SEGMENTS

OUT = Path(__file__).resolve().parent.parent / "docs" / "images" / "bodies"


def segment_colours(n: int) -> np.ndarray:
    """n colours far apart (hues around the circle, alternating light and dark), RGB in [0, 1]."""
    import colorsys

    return np.array([colorsys.hls_to_rgb((k * 0.61803398875) % 1.0, 0.45 if k % 2 else 0.65, 0.7) for k in range(n)])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pose", default="leaning-forward")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        glb = save_gltf_body(Path(tmp) / "default-female.glb", load_rig("default-female"))
        rig = load_gltf_body(glb, sex="female")
    palette = segment_colours(len(SEGMENTS))
    dominant = np.argmax(rig.weights, axis=1)
    render_body(rig, OUT / "gltf-default-female.png", colors=palette[dominant], legend=list(zip(SEGMENTS, palette)),
                scalar_label="segment", show_skeleton=True, title="default-female written as GLB and read back (colour: the segment weighing most on a vertex)")
    posed = pose_rig(rig, load_pose(args.pose))
    render_body(posed, OUT / "gltf-posed.png", show_skeleton=True, title=f"the GLB-imported body posed: {args.pose}")
    print(OUT / "gltf-default-female.png", OUT / "gltf-posed.png")


if __name__ == "__main__":
    main()
