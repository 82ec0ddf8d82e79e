"""Can the 3x7 chair hold this pose? A rule on the posed skeleton, decided before any fitting.

The chair's grid runs from the feet up the legs, under the pelvis and up the
back, with the legs side by side in front of the trunk (paper Sec. 5). The
rule measures, on the posed skeleton (joints and bone tips; the skin only
for the floor, the soles and the hands; no pressure), the things that grid cannot follow (paper Sec. 6 and
docs/templates.md, "The pose rule"):

- **lying on the side**: the body's left-right axis (hips and shoulders)
  tilted more than ``max_roll_deg`` from horizontal: the columns would stack;
- **a leg reaching back**: a thigh within 45 deg of level whose knee is
  less than ``min_knee_ahead`` thigh lengths ahead of the hip joint (along
  the body's facing direction): behind the hip, as in a lunge or a yoga
  pose with one knee back; the leg columns run forward from the seat to the
  feet, and the bridges between a leg forward and a leg back would cross
  the seat (a thigh pointing down, standing or kneeling, is the standing
  and kneeling tests' concern);
- **sitting sideways**: a thigh turned more than ``max_thigh_turn_deg``
  from straight ahead towards the line across the shoulders, seen from above: the leg columns would leave
  the seat sideways and cross the back's columns;
- **feet under the body**: a shank swung back under its thigh, the foot
  more than ``max_shank_back_deg`` behind the vertical through the knee
  (towards the trunk) and either less than ``min_foot_ahead`` thigh lengths
  ahead of the hip joint (along the body's facing direction) or more than
  ``max_shank_back_foot_ahead_deg`` behind: the calf lies under the seat,
  and a seat under the thigh would cut through it (a shank swung back a
  little under a thigh that reaches far ahead leaves the calf in front of
  the seat: the chair holds it);
- **kneeling**: the same, with the knee within ``kneel_height`` of the
  floor and the thigh more than 45 deg below level: the body rests on the shins, which the chair's leg rows cannot
  reach from below;
- **a hand on the floor**: a hand within ``hand_floor`` of the floor (the
  body propped on it, the buttocks just above the ground): the chair stands
  on the floor around the seat, and its side down to the ground would pass
  through the hand. Otherwise hands are not refused: hanging beside the
  seat, on the thighs, beside or behind a calf, the chair is built around
  them (the fit repairs the faces an arm meets; docs/templates.md, "The
  pose rule");
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
    "min_foot_ahead": 0.25,
    "min_knee_ahead": 0.0,
    "max_shank_back_foot_ahead_deg": 45.0,
    "kneel_height": 0.2,
    "hand_floor": 0.03,
}

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
        ``roll_deg``, per leg ``thigh_turn_deg``, ``shank_back_deg``,
        ``foot_ahead_thighs``, ``knee_height_m`` and ``thigh_down_deg``, and
        the limits used.
    """

    supportable: bool
    reasons: list = field(default_factory=list)
    parts: list = field(default_factory=list)
    measures: dict = field(default_factory=dict)


def _horizontal(v: np.ndarray) -> np.ndarray:
    return v - _UP * (v @ _UP)


def assess_pose(body: Body, rule: Mapping[str, Any] | None = None) -> PoseVerdict:
    """Apply the pose rule to a posed body (grounded: its lowest vertex at y = 0).

    Parameters
    ----------
    body : Body
    rule : mapping, optional
        Thresholds overriding :data:`DEFAULT_RULE` (degrees, metres).
    """
    r = {**DEFAULT_RULE, **dict(rule or {})}
    j, tips = body.joints, body.tips
    floor = float(body.vertices[:, 1].min())
    lat = _unit(_unit(j[S["LeftUpLeg"]] - j[S["RightUpLeg"]]) + _unit(j[S["LeftArm"]] - j[S["RightArm"]]))
    roll = float(np.degrees(np.arcsin(min(1.0, abs(lat[1])))))
    trunk = _unit(tips[S["Spine3"]] - j[S["Hips"]])
    front = _unit(_horizontal(np.cross(lat, trunk)))
    # the direction the body faces, seen from above (as seatkit.body.frame finds it; the chest's when lying on the side)
    facing = _unit(np.cross(_horizontal(lat), _UP)) if np.linalg.norm(_horizontal(lat)) > 0.3 else front
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
        # how far the foot (ankle joint) is ahead of the hip joint, in thigh lengths, along the facing direction
        ahead = float((ankle - hip) @ facing) / max(float(np.linalg.norm(thigh)), 1e-9)
        # how far the knee is ahead of the hip joint, in thigh lengths, along the facing direction
        knee_ahead = float(thigh @ facing) / max(float(np.linalg.norm(thigh)), 1e-9)
        leg = {
            "thigh_turn_deg": turn, "shank_back_deg": back, "knee_height_m": knee_h, "thigh_down_deg": thigh_down,
            "foot_ahead_thighs": ahead, "knee_ahead_thighs": knee_ahead,
        }
        measures["legs"][side] = leg
        name = side.lower()
        if roll <= r["max_roll_deg"] and thigh_down < 45.0 and knee_ahead < r["min_knee_ahead"]:
            reasons.append(
                f"a leg reaching back: the {name} knee is {-knee_ahead:.2f} thigh lengths behind the hip joint (it must be at least "
                f"{r['min_knee_ahead']:.2f} ahead) with the thigh {abs(thigh_down):.0f} deg from level: the chair's leg columns run forward "
                "from the seat, and the bridge to the other leg would cross the seat"
            )
            parts += [side + "UpLeg", side + "Leg"]
        elif roll <= r["max_roll_deg"] and turn > r["max_thigh_turn_deg"]:
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
        elif back > r["max_shank_back_deg"] and (ahead < r["min_foot_ahead"] or back > r["max_shank_back_foot_ahead_deg"]):
            reasons.append(
                f"feet under the body: the {name} foot is swung back {back:.0f} deg behind the knee (at most "
                f"{r['max_shank_back_deg']:.0f}, or {r['max_shank_back_foot_ahead_deg']:.0f} with the foot at least {r['min_foot_ahead']:.2f} "
                f"thigh lengths ahead of the hip; it is {ahead:.2f}): the calf lies under the seat, which would cut through it"
            )
            parts += [side + "Leg", side + "UpLeg"]
    # where the hands are, for the record (no limit: see the module docstring)
    hips_c = 0.5 * (j[S["LeftUpLeg"]] + j[S["RightUpLeg"]])
    half = 0.5 * float(np.linalg.norm(j[S["LeftUpLeg"]] - j[S["RightUpLeg"]]))
    hip_axis = _unit(j[S["LeftUpLeg"]] - j[S["RightUpLeg"]])
    trunk_tilt = float(np.degrees(np.arccos(np.clip(trunk @ _UP, -1.0, 1.0))))
    measures.update({"trunk_tilt_deg": trunk_tilt, "hands": {}})
    seg = segment_of_vertex(body)
    for side in ("Right", "Left"):
        wrist = j[S[side + "Hand"]]
        hand = body.vertices[seg == S[side + "Hand"], 1]
        above_floor = float(hand.min() - floor) if len(hand) else float("inf")
        measures["hands"][side] = {"above_hips_m": float(wrist[1] - hips_c[1]), "outside_hips_m": abs(float((wrist - hips_c) @ hip_axis)) - half, "above_floor_m": above_floor}
        if above_floor <= r["hand_floor"]:
            reasons.append(
                f"a hand on the floor: the {side.lower()} hand is {100 * above_floor:.0f} cm above the floor (at least {100 * r['hand_floor']:.0f}): "
                "the chair stands on the floor around the seat and its side would pass through the hand; lift the hand onto the thigh or beside it"
            )
            parts.append(side + "Hand")
    # standing on its own feet: both thighs pointing down and the centre of
    # mass above the soles' footprint (along the facing direction), so the
    # body needs no support (standing-leaning-back has its centre of mass
    # behind the heels: it leans on the support)
    com = (body.segment_mass[:, None] * body.segment_com).sum(axis=0) / float(body.segment_mass.sum())
    feet = np.isin(seg, [S["LeftFoot"], S["RightFoot"]])
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


class PoseRuleStep:
    """Refuse, before any fitting, the poses the template's grid cannot follow (:func:`assess_pose`)."""

    name = "pose-rule"
    description = "refuse poses the grid cannot follow (lying on the side, a leg reaching back, sitting sideways, feet under the body, kneeling, a hand on the floor, standing upright), from the skeleton, before fitting"
    stage = "blocks"
    requires = ()
    options = {
        "max_roll_deg": Option("number", "largest tilt of the body's left-right axis from horizontal", DEFAULT_RULE["max_roll_deg"], "deg", 0.0, 90.0),
        "max_thigh_turn_deg": Option("number", "largest turn of a thigh from straight ahead towards the line across the shoulders, seen from above", DEFAULT_RULE["max_thigh_turn_deg"], "deg", 0.0, 180.0),
        "max_shank_back_deg": Option("number", "largest swing of a shank behind the vertical through its knee (unless its foot is at least min_foot_ahead ahead of the hip)", DEFAULT_RULE["max_shank_back_deg"], "deg", 0.0, 180.0),
        "max_shank_back_foot_ahead_deg": Option("number", "largest swing of a shank behind the vertical through its knee when its foot is at least min_foot_ahead ahead of the hip", DEFAULT_RULE["max_shank_back_foot_ahead_deg"], "deg", 0.0, 180.0),
        "min_foot_ahead": Option("number", "a shank swung back further than max_shank_back_deg is refused when its foot is less than this far ahead of the hip joint", DEFAULT_RULE["min_foot_ahead"], "1", -2.0, 2.0),
        "min_knee_ahead": Option("number", "a thigh within 45 deg of level is refused when its knee is less than this far ahead of the hip joint (reaching back)", DEFAULT_RULE["min_knee_ahead"], "1", -2.0, 2.0),
        "kneel_height": Option("number", "a knee this close to the floor with its shank swung back is kneeling", DEFAULT_RULE["kneel_height"], "m", 0.0, 2.0),
        "hand_floor": Option("number", "a hand this close to the floor (the body propped on it) is refused: the chair's side down to the ground would pass through it", DEFAULT_RULE["hand_floor"], "m", 0.0, 2.0),
    }

    def run(self, state, *, options: Mapping[str, Any]) -> None:
        from seatkit.template.checks import person_label

        rule = {k: float(v) for k, v in options.items()}
        verdicts = []
        for block in state.blocks:
            v = assess_pose(block.body, rule)
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
