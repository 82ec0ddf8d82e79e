"""Segment masses and centres of mass of the 21-segment skeleton.

The paper (Section 4.1) takes segment masses and centre-of-mass positions from
Plagenhoef, Evans and Abdelnour (1983), "Anatomical data for analyzing human
motion", Research Quarterly for Exercise and Sport 54(2):169-178. Their table
gives, in per cent of total body mass:

==================  =====  =======
segment             males  females
==================  =====  =======
head and neck        8.26     8.20
thorax              20.10    17.02
abdomen             13.06    12.24
pelvis              13.66    15.96
upper arm (each)     3.25     2.90
forearm (each)       1.87     1.57
hand (each)          0.65     0.50
thigh (each)        10.50    11.75
leg/shank (each)     4.75     5.35
foot (each)          1.43     1.33
==================  =====  =======

(The "whole trunk" of 55.10 / 53.20 % in the same table is head and neck plus
thorax, abdomen and pelvis; the three trunk parts are used here.) The male
column sums to 99.98 %, the female one to 100.22 %; both are rescaled to sum
to exactly 1.

Centres of mass, in per cent of the segment length from the proximal end:
upper arm 43.6 / 45.8, forearm 43.0 / 43.4, hand 46.8 / 46.8, thigh 43.3 /
42.8, leg 43.4 / 41.9, foot 50.0 / 50.0, head and neck 55.0 / 55.0. The trunk
parts have no separate values in the table; each trunk sub-segment (and the
shoulder girdle) uses the mid-point, 50 %, the trunk estimate that Winter
(1990) derives from Dempster (1955) data.

How the table's parts are split across the Perception Neuron segments (these
splits are this project's choice; the paper does not state its own):

- ``Hips`` (hip centre to the lumbar joint) = pelvis.
- ``Spine``, ``Spine1`` (lumbar) = abdomen, half each.
- ``Spine2``, ``Spine3`` (thoracic) and the two ``Shoulder`` (clavicle)
  segments = thorax: each shoulder girdle gets 1.0 % of body mass (Plagenhoef's
  thorax includes the shoulder girdle: the upper arm starts at the shoulder
  joint), the rest is split half and half between ``Spine2`` and ``Spine3``.
- ``Neck`` = 20 % of head and neck, ``Head`` = 80 % of it.
- ``Arm`` = upper arm, ``ForeArm`` = forearm, ``Hand`` = hand, ``UpLeg`` =
  thigh, ``Leg`` = leg (shank), ``Foot`` = foot.
"""

from __future__ import annotations

import numpy as np

from seatkit.errors import RecipeError
from seatkit.skeleton import SEGMENTS

__all__ = ["PLAGENHOEF_1983", "SEXES", "body_density", "segment_mass_fractions", "com_ratios", "segment_masses"]

#: Plagenhoef et al. (1983): per cent of body mass and centre of mass in per
#: cent of segment length from the proximal end, by sex.
PLAGENHOEF_1983: dict[str, dict[str, dict[str, float]]] = {
    "male": {
        "mass_percent": {
            "head_neck": 8.26,
            "thorax": 20.10,
            "abdomen": 13.06,
            "pelvis": 13.66,
            "upper_arm": 3.25,
            "forearm": 1.87,
            "hand": 0.65,
            "thigh": 10.50,
            "leg": 4.75,
            "foot": 1.43,
        },
        "com_percent": {
            "head_neck": 55.0,
            "upper_arm": 43.6,
            "forearm": 43.0,
            "hand": 46.8,
            "thigh": 43.3,
            "leg": 43.4,
            "foot": 50.0,
        },
    },
    "female": {
        "mass_percent": {
            "head_neck": 8.20,
            "thorax": 17.02,
            "abdomen": 12.24,
            "pelvis": 15.96,
            "upper_arm": 2.90,
            "forearm": 1.57,
            "hand": 0.50,
            "thigh": 11.75,
            "leg": 5.35,
            "foot": 1.33,
        },
        "com_percent": {
            "head_neck": 55.0,
            "upper_arm": 45.8,
            "forearm": 43.4,
            "hand": 46.8,
            "thigh": 42.8,
            "leg": 41.9,
            "foot": 50.0,
        },
    },
}

SEXES = tuple(PLAGENHOEF_1983)

#: Per cent of body mass given to each shoulder girdle (clavicle) segment,
#: taken out of the thorax.
SHOULDER_GIRDLE_PERCENT = 1.0
#: Share of head-and-neck mass given to the Neck segment.
NECK_SHARE = 0.2
#: Centre of mass of trunk sub-segments and shoulders, fraction of length.
TRUNK_COM_RATIO = 0.5


def _check_sex(sex: str) -> dict:
    try:
        return PLAGENHOEF_1983[sex]
    except KeyError:
        msg = f"unknown sex {sex!r} for the Plagenhoef table; expected one of {', '.join(SEXES)}"
        raise RecipeError(msg) from None


def segment_mass_fractions(sex: str = "male") -> np.ndarray:
    """Fraction of body mass in each of the 21 segments.

    Parameters
    ----------
    sex : {"male", "female"}
        Which column of Plagenhoef et al. (1983).

    Returns
    -------
    fractions : (21,) float64
        In :data:`seatkit.skeleton.SEGMENTS` order; non-negative, summing to 1
        (to rounding).
    """
    p = _check_sex(sex)["mass_percent"]
    thorax_rest = p["thorax"] - 2.0 * SHOULDER_GIRDLE_PERCENT
    per_segment = {
        "Hips": p["pelvis"],
        "RightUpLeg": p["thigh"],
        "RightLeg": p["leg"],
        "RightFoot": p["foot"],
        "LeftUpLeg": p["thigh"],
        "LeftLeg": p["leg"],
        "LeftFoot": p["foot"],
        "Spine": p["abdomen"] / 2.0,
        "Spine1": p["abdomen"] / 2.0,
        "Spine2": thorax_rest / 2.0,
        "Spine3": thorax_rest / 2.0,
        "Neck": p["head_neck"] * NECK_SHARE,
        "Head": p["head_neck"] * (1.0 - NECK_SHARE),
        "RightShoulder": SHOULDER_GIRDLE_PERCENT,
        "RightArm": p["upper_arm"],
        "RightForeArm": p["forearm"],
        "RightHand": p["hand"],
        "LeftShoulder": SHOULDER_GIRDLE_PERCENT,
        "LeftArm": p["upper_arm"],
        "LeftForeArm": p["forearm"],
        "LeftHand": p["hand"],
    }
    percent = np.array([per_segment[name] for name in SEGMENTS], dtype=np.float64)
    return percent / percent.sum()


def com_ratios(sex: str = "male") -> np.ndarray:
    """Centre of mass of each segment along joint -> tip, as a fraction.

    Parameters
    ----------
    sex : {"male", "female"}

    Returns
    -------
    ratios : (21,) float64
        0 is the proximal joint, 1 the tip.
    """
    c = {k: v / 100.0 for k, v in _check_sex(sex)["com_percent"].items()}
    per_segment = {
        "Hips": TRUNK_COM_RATIO,
        "RightUpLeg": c["thigh"],
        "RightLeg": c["leg"],
        "RightFoot": c["foot"],
        "LeftUpLeg": c["thigh"],
        "LeftLeg": c["leg"],
        "LeftFoot": c["foot"],
        "Spine": TRUNK_COM_RATIO,
        "Spine1": TRUNK_COM_RATIO,
        "Spine2": TRUNK_COM_RATIO,
        "Spine3": TRUNK_COM_RATIO,
        "Neck": TRUNK_COM_RATIO,
        "Head": c["head_neck"],
        "RightShoulder": TRUNK_COM_RATIO,
        "RightArm": c["upper_arm"],
        "RightForeArm": c["forearm"],
        "RightHand": c["hand"],
        "LeftShoulder": TRUNK_COM_RATIO,
        "LeftArm": c["upper_arm"],
        "LeftForeArm": c["forearm"],
        "LeftHand": c["hand"],
    }
    return np.array([per_segment[name] for name in SEGMENTS], dtype=np.float64)


def segment_masses(mass: float, sex: str = "male") -> np.ndarray:
    """Segment masses for a body of ``mass`` kg.

    Parameters
    ----------
    mass : float
        Total body mass, kg; must be positive and finite.
    sex : {"male", "female"}

    Returns
    -------
    masses : (21,) float64
        kg, summing to ``mass``.
    """
    mass = float(mass)
    if not np.isfinite(mass) or mass <= 0.0:
        msg = f"body mass must be a positive number of kg, got {mass}"
        raise RecipeError(msg)
    fractions = segment_mass_fractions(sex)
    masses = fractions * mass
    # put the rounding residue on the heaviest segment so the sum is exact
    masses[int(np.argmax(masses))] += mass - masses.sum()
    return masses


def body_density(stature: float, mass: float) -> float:
    """Whole-body density, kg/m^3: Contini (1972), ``0.69 + 0.9 h / m^(1/3)`` kg/l."""
    return 1000.0 * (0.69 + 0.9 * stature / mass ** (1.0 / 3.0))
