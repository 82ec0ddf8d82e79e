"""Can the 3x7 chair hold this pose? A rule on the posed skeleton, decided before any fitting.

The chair's grid runs from the feet up the legs, under the pelvis and up the
back, with the legs side by side in front of the trunk (paper Sec. 5). The
rule measures, on the posed skeleton (joints and bone tips) and, for the
hands, the skin and the pressure's importance (no fitting), the things that
grid cannot follow (paper Sec. 6 and docs/templates.md, "The pose rule"):

- **lying on the side**: the body's left-right axis (hips and shoulders)
  tilted more than ``max_roll_deg`` from horizontal: the columns would stack;
- **sitting sideways**: a thigh turned more than ``max_thigh_turn_deg``
  from straight ahead towards the line across the shoulders, seen from above: the leg columns would leave
  the seat sideways and cross the back's columns;
- **feet under the body**: a shank swung back under its thigh, the foot
  more than ``max_shank_back_deg`` behind the vertical through the knee
  (towards the trunk): a seat under the thigh would cut through the calf;
- **kneeling**: the same, with the knee within ``kneel_height`` of the
  floor and the thigh more than 45 deg below level: the body rests on the shins, which the chair's leg rows cannot
  reach from below;
- **a loaded part resting on a hand** (given the pressure's importance):
  more than ``max_load_on_hands`` of the load of a thigh, a shank or the
  pelvis (its important vertices, weighted) has a hand or forearm straight
  below it: the chair's surface under that part would have to pass through
  the hand. Hands hanging beside the seat, on the thighs or in the lap are
  not refused: the fit repairs the faces they meet (docs/templates.md);
- **standing on its own feet**: both thighs more than 45 deg below level and
  the centre of mass above the soles' footprint: the body needs no support
  and leans on nothing the chair could give.

:func:`assess_pose` returns a :class:`PoseVerdict` with every measure, so
``seatkit poses --check`` can say why; the ``pose-rule`` template step
raises :class:`seatkit.errors.UnsupportedPoseError` with the same reasons.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from seatkit.errors import UnsupportedPoseError
from seatkit.model import Body
from seatkit.skeleton import SEGMENT_INDEX as S
from seatkit.template.grid import segment_of_vertex
from seatkit.template.options import Option

__all__ = ["DEFAULT_RULE", "PoseVerdict", "assess_pose", "PoseRuleStep", "template_rule"]

#: The rule's thresholds (the chair's values, see docs/templates.md).
DEFAULT_RULE = {
    "max_roll_deg": 45.0,
    "max_thigh_turn_deg": 50.0,
    "max_shank_back_deg": 25.0,
    "kneel_height": 0.2,
    "max_load_on_hands": 0.2,
}

#: A vertex is important at this share of the peak importance (the template parameter ``important_threshold``).
IMPORTANT = 0.05
#: The parts a chair holds from below, whose load must not rest on a hand.
_HELD_FROM_BELOW = ("Hips", "RightUpLeg", "LeftUpLeg", "RightLeg", "LeftLeg")
_HAND_PARTS = ("RightHand", "LeftHand", "RightForeArm", "LeftForeArm")

_UP = np.array([0.0, 1.0, 0.0])


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else v * 0.0


@dataclass(frozen=True)
class PoseVerdict:
    """What the rule found.

    Attributes
    ----------
    supportable : bool
    reasons : list of str
        One sentence per violated limit, for a designer.
    parts : list of str
        The segments concerned.
    measures : dict
        ``roll_deg``, per leg ``thigh_turn_deg``, ``shank_back_deg`` and
        ``knee_height_m``, and the limits used.
    """

    supportable: bool
    reasons: list = field(default_factory=list)
    parts: list = field(default_factory=list)
    measures: dict = field(default_factory=dict)


def _horizontal(v: np.ndarray) -> np.ndarray:
    return v - _UP * (v @ _UP)


def assess_pose(body: Body, rule: Mapping[str, Any] | None = None, importance: np.ndarray | None = None) -> PoseVerdict:
    """Apply the pose rule to a posed body (grounded: its lowest vertex at y = 0).

    Parameters
    ----------
    body : Body
    rule : mapping, optional
        Thresholds overriding :data:`DEFAULT_RULE` (degrees, metres).
    importance : (n,) float64, optional
        The pressure's per-vertex importance (:class:`seatkit.model.PressureField`);
        without it, the load-on-a-hand test is skipped.
    """
    r = {**DEFAULT_RULE, **dict(rule or {})}
    j, tips = body.joints, body.tips
    floor = float(body.vertices[:, 1].min())
    lat = _unit(_unit(j[S["LeftUpLeg"]] - j[S["RightUpLeg"]]) + _unit(j[S["LeftArm"]] - j[S["RightArm"]]))
    roll = float(np.degrees(np.arcsin(min(1.0, abs(lat[1])))))
    trunk = _unit(tips[S["Spine3"]] - j[S["Hips"]])
    front = _unit(_horizontal(np.cross(lat, trunk)))
    # the trunk's left-right axis seen from above (the shoulders: the pelvis turns with the legs)
    shoulders = _unit(_horizontal(j[S["LeftArm"]] - j[S["RightArm"]]))
    measures: dict = {"roll_deg": roll, "limits": dict(r), "legs": {}}
    reasons, parts = [], []
    if roll > r["max_roll_deg"]:
        reasons.append(
            f"the body lies on its side (left-right axis tilted {roll:.0f} deg, at most {r['max_roll_deg']:.0f}): "
            "the chair's columns would stack on top of each other"
        )
        parts += ["Hips", "Spine"]
    for side in ("Right", "Left"):
        hip, knee, ankle = j[S[side + "UpLeg"]], j[S[side + "Leg"]], j[S[side + "Foot"]]
        thigh, shank = knee - hip, ankle - knee
        th = _horizontal(thigh)
        # the thigh's heading seen from above, against the line across the
        # shoulders: 0 deg straight ahead (or back, lying), 90 deg along the
        # shoulders (only meaningful when the thigh is not nearly vertical)
        if np.linalg.norm(th) > 0.35 * np.linalg.norm(thigh):
            turn = float(np.degrees(np.arcsin(min(1.0, abs(float(_unit(th) @ shoulders))))))
        else:
            turn = 0.0
        # the shank's swing behind the vertical through the knee, along the thigh's heading
        heading = _unit(th) if np.linalg.norm(th) > 0.35 * np.linalg.norm(thigh) else front
        back = float(np.degrees(np.arctan2(-(shank @ heading), max(-(shank @ _UP), 1e-9))))
        knee_h = float(knee[1] - floor)
        thigh_down = float(np.degrees(np.arcsin(np.clip(-_unit(thigh) @ _UP, -1.0, 1.0))))
        leg = {"thigh_turn_deg": turn, "shank_back_deg": back, "knee_height_m": knee_h, "thigh_down_deg": thigh_down}
        measures["legs"][side] = leg
        name = side.lower()
        if roll <= r["max_roll_deg"] and turn > r["max_thigh_turn_deg"]:
            reasons.append(
                f"sitting sideways: the {name} thigh is turned {turn:.0f} deg from straight ahead towards the shoulders' line (at most "
                f"{r['max_thigh_turn_deg']:.0f}): the leg columns would leave the seat beside the backrest"
            )
            parts.append(side + "UpLeg")
        elif back > r["max_shank_back_deg"] and knee_h <= r["kneel_height"] and thigh_down > 45.0:
            reasons.append(
                f"kneeling: the {name} knee is {100 * knee_h:.0f} cm above the floor with the shin swung back "
                f"{back:.0f} deg under the thigh: the chair cannot reach the shins from below"
            )
            parts += [side + "Leg", side + "UpLeg"]
        elif back > r["max_shank_back_deg"]:
            reasons.append(
                f"feet under the body: the {name} foot is swung back {back:.0f} deg behind the knee (at most "
                f"{r['max_shank_back_deg']:.0f}): a seat under the thigh would cut through the calf"
            )
            parts += [side + "Leg", side + "UpLeg"]
    # where the hands are, for the record; the load resting on them, when the pressure is given
    hips_c = 0.5 * (j[S["LeftUpLeg"]] + j[S["RightUpLeg"]])
    half = 0.5 * float(np.linalg.norm(j[S["LeftUpLeg"]] - j[S["RightUpLeg"]]))
    hip_axis = _unit(j[S["LeftUpLeg"]] - j[S["RightUpLeg"]])
    trunk_tilt = float(np.degrees(np.arccos(np.clip(trunk @ _UP, -1.0, 1.0))))
    measures.update({"trunk_tilt_deg": trunk_tilt, "hands": {}})
    for side in ("Right", "Left"):
        wrist = j[S[side + "Hand"]]
        measures["hands"][side] = {"above_hips_m": float(wrist[1] - hips_c[1]), "outside_hips_m": abs(float((wrist - hips_c) @ hip_axis)) - half}
    if importance is not None:
        on_hands = load_on_hands(body, np.asarray(importance, dtype=np.float64))
        measures["load_on_hands"] = on_hands
        for part, (share, hand) in on_hands.items():
            if share > r["max_load_on_hands"]:
                reasons.append(
                    f"the {_NAMES[part]} rests on the {_NAMES[hand]} ({100 * share:.0f}% of its load has the hand straight below it, "
                    f"at most {100 * r['max_load_on_hands']:.0f}%): the chair's surface under it would pass through the hand; "
                    "move the hand beside the leg, onto the thigh or onto an armrest"
                )
                parts += [part, hand]
    # standing on its own feet: both thighs pointing down and the centre of
    # mass above the soles' footprint (along the facing direction), so the
    # body needs no support (standing-leaning-back has its centre of mass
    # behind the heels: it leans on the support)
    com = (body.segment_mass[:, None] * body.segment_com).sum(axis=0) / float(body.segment_mass.sum())
    feet = np.isin(segment_of_vertex(body), [S["LeftFoot"], S["RightFoot"]])
    sole = body.vertices[feet & (body.vertices[:, 1] < floor + 0.03)] @ front
    standing = all(leg["thigh_down_deg"] > 45.0 for leg in measures["legs"].values())
    if standing and len(sole):
        ahead = float(com @ front - sole.min())
        measures["com_ahead_of_heels_m"] = ahead
        if 0.0 <= ahead <= float(sole.max() - sole.min()):
            reasons.append(
                f"standing on its own feet: the centre of mass is above the soles ({100 * ahead:.0f} cm ahead of the heels) "
                "and the thighs point down, so the body leans on nothing a chair could carry; lean it back against the support "
                "(as standing-leaning-back) or sit"
            )
            parts += ["Hips", "Spine"]
    return PoseVerdict(not reasons, reasons, sorted(set(parts)), measures)


_NAMES = {
    "Hips": "pelvis", "RightUpLeg": "right thigh", "LeftUpLeg": "left thigh", "RightLeg": "right calf", "LeftLeg": "left calf",
    "RightHand": "right hand", "LeftHand": "left hand", "RightForeArm": "right forearm", "LeftForeArm": "left forearm",
}


def load_on_hands(body: Body, importance: np.ndarray, threshold: float = IMPORTANT) -> dict:
    """{part: (share, hand part)} of the parts a chair holds from below whose load has a hand straight below it.

    For each of :data:`_HELD_FROM_BELOW`, its important vertices (importance
    at least ``threshold`` of the peak) each cast a ray straight down to the
    floor (the paper's "shortest line to the ground" under a seat); the share
    is the importance of those whose first body crossing is a hand or a
    forearm, over the part's whole importance. Parts with no important
    vertex or no such share are left out.
    """
    from seatkit.template.checks import cast_parallel

    seg = segment_of_vertex(body)
    V = np.asarray(body.vertices, dtype=np.float64)
    F = np.asarray(body.faces)
    hands = [S[h] for h in _HAND_PARTS]
    peak = float(importance.max()) if len(importance) else 0.0
    out = {}
    for part in _HELD_FROM_BELOW:
        iv = np.flatnonzero((importance >= threshold * peak) & (seg == S[part])) if peak > 0 else np.zeros(0, np.int64)
        if len(iv) == 0:
            continue
        _, tri = cast_parallel(body, V[iv] - 2e-3 * _UP, -_UP, np.maximum(V[iv, 1], 1e-6))
        hit_seg = seg[F[np.where(tri >= 0, tri, 0), 0]]
        on = (tri >= 0) & np.isin(hit_seg, hands)
        if on.any():
            w = importance[iv]
            hand = int(np.bincount(hit_seg[on], weights=w[on]).argmax())
            out[part] = (float(w[on].sum() / w.sum()), next(h for h in _HAND_PARTS if S[h] == hand))
    return out


class PoseRuleStep:
    """Refuse, before any fitting, the poses the template's grid cannot follow (:func:`assess_pose`)."""

    name = "pose-rule"
    description = "refuse poses the grid cannot follow (lying on the side, sitting sideways, feet under the body, kneeling, standing upright, a thigh or calf resting on a hand), from the skeleton and the pressure, before fitting"
    stage = "blocks"
    requires = ()
    options = {
        "max_roll_deg": Option("number", "largest tilt of the body's left-right axis from horizontal", DEFAULT_RULE["max_roll_deg"], "deg", 0.0, 90.0),
        "max_thigh_turn_deg": Option("number", "largest turn of a thigh from straight ahead towards the line across the shoulders, seen from above", DEFAULT_RULE["max_thigh_turn_deg"], "deg", 0.0, 180.0),
        "max_shank_back_deg": Option("number", "largest swing of a shank behind the vertical through its knee", DEFAULT_RULE["max_shank_back_deg"], "deg", 0.0, 180.0),
        "kneel_height": Option("number", "a knee this close to the floor with its shank swung back is kneeling", DEFAULT_RULE["kneel_height"], "m", 0.0, 2.0),
        "max_load_on_hands": Option("number", "largest share of a thigh's, calf's or the pelvis's load that may have a hand or forearm straight below it", DEFAULT_RULE["max_load_on_hands"], "1", 0.0, 1.0),
    }

    def run(self, state, *, options: Mapping[str, Any]) -> None:
        from seatkit.template.checks import person_label

        rule = {k: float(v) for k, v in options.items()}
        verdicts = []
        for block in state.blocks:
            v = assess_pose(block.body, rule, block.importance)
            verdicts.append({"person": block.person, "supportable": v.supportable, "reasons": v.reasons, **v.measures})
            state.meta["pose_rule"] = verdicts
            if not v.supportable:
                who = person_label(block.person, block.body)
                msg = f"{who}: the {state.spec.name} template cannot support {', '.join(v.parts)} in this pose: {'; '.join(v.reasons)}"
                err = UnsupportedPoseError(msg, parts=v.parts, diagnostics={"pose_rule": verdicts})
                err.seed_independent = True  # no other RANSAC start changes the skeleton
                raise err


def template_rule(template) -> dict | None:
    """The options of ``template``'s ``pose-rule`` step (``{}`` for the defaults), or None when it has none."""
    spec = getattr(template, "spec", None)
    for step in getattr(spec, "steps", ()) or ():
        if step.get("step") == PoseRuleStep.name:
            return {k: float(v) for k, v in step.items() if k not in ("step", "label")}
    return None
