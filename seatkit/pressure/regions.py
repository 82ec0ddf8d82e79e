"""The paper's user weights nu (Appendix A): regions that carry no reaction.

In Appendix A ``nu`` multiplies a vertex's reaction both in the equilibrium
rows (matrix C) and in the objective (matrix A). Substituting
``r' = nu r`` removes it from both, so only ``nu = 0`` changes the solution:
it takes the vertex out of the contact set. We implement nu as exactly that,
named regions whose vertices are removed from the contact set.

Default exclusions (:data:`DEFAULT_EXCLUDE`), with the reasons given in
``docs/physics.md``:

- ``face``: without it the four highest pressures of a seated body are
  under the nose, lips and chin.
- ``chin``: the underside of the jaw and the front of the throat (head and
  neck skin in front of the head's axis, below 35 % of its length), which a
  face label may not cover; no support carries a body by its chin.
- ``hands``: a hand resting on the thigh is self-contact, and no chair
  supports fingers; without the exclusion a large share of the arm's weight
  sits in the palms.
- ``abdomen``: the front of the belly, which folds onto the thighs when
  seated (self-contact, not a support).

Forearms stay in the contact set: the chair template builds armrests under
them and needs their pressure as importance.

Bodies carry ``region_labels`` (name -> vertex indices). Where a name is
missing we fall back to a geometric definition from skinning weights and
posed joints (see :func:`region_vertices`).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from seatkit.errors import InputError
from seatkit.skeleton import SEGMENT_INDEX

__all__ = ["DEFAULT_EXCLUDE", "GEOMETRIC_REGIONS", "region_vertices", "exclusion_mask"]

#: Regions excluded from support by default (nu = 0).
DEFAULT_EXCLUDE: tuple[str, ...] = ("face", "chin", "hands", "abdomen")

#: Region names that have a geometric fallback.
GEOMETRIC_REGIONS: tuple[str, ...] = ("face", "chin", "hands", "forearms", "abdomen", "head")


def _dominant(weights: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """Vertices whose skinning weight on the named segments is above 0.5."""
    cols = [SEGMENT_INDEX[n] for n in names]
    return weights[:, cols].sum(axis=1) > 0.5


def _forward(body, up: np.ndarray | None = None) -> np.ndarray:
    """Posed forward direction: shoulder line (right to left) x ``up``.

    ``up`` defaults to the trunk axis (Spine joint to Spine3 tip). In the
    rest pose this is +X x +Y = +Z; it turns with the body whatever the pose
    (lying, reclined), unlike the world's +Z.
    """
    if up is None:
        up = body.tips[SEGMENT_INDEX["Spine3"]] - body.joints[SEGMENT_INDEX["Spine"]]
    up = up / max(np.linalg.norm(up), 1e-12)
    across = body.joints[SEGMENT_INDEX["LeftArm"]] - body.joints[SEGMENT_INDEX["RightArm"]]
    fwd = np.cross(across, up)
    return fwd / max(np.linalg.norm(fwd), 1e-12)


def _geometric_region(body, name: str, normals: np.ndarray) -> np.ndarray:
    w = body.weights
    v = body.vertices
    if name == "hands":
        return np.flatnonzero(_dominant(w, ["RightHand", "LeftHand"]))
    if name == "forearms":
        return np.flatnonzero(_dominant(w, ["RightForeArm", "LeftForeArm"]))
    if name == "head":
        return np.flatnonzero(_dominant(w, ["Head"]))
    if name in ("face", "chin"):
        # head (and upper neck) vertices in front of the head's bone axis
        head = SEGMENT_INDEX["Head"]
        base, tip = body.joints[head], body.tips[head]
        axis = (tip - base) / max(np.linalg.norm(tip - base), 1e-12)
        fwd = _forward(body, axis)
        rel = v - base
        along = rel @ axis
        ahead = rel @ fwd
        in_head = _dominant(w, ["Head", "Neck"])
        length = np.linalg.norm(tip - base)
        if name == "chin":
            sel = in_head & (ahead > 0.0) & (along < 0.35 * length)
        else:
            sel = in_head & (ahead > 0.02) & (along > -0.25 * length)
        return np.flatnonzero(sel)
    if name == "abdomen":
        # front of the lower trunk: skin of Hips/Spine/Spine1 facing forward,
        # above the hip joints
        trunk = _dominant(w, ["Hips", "Spine", "Spine1"])
        fwd = _forward(body)
        hips_y = body.joints[SEGMENT_INDEX["Hips"]][1]
        sel = trunk & (normals @ fwd > 0.3) & (v[:, 1] > hips_y)
        return np.flatnonzero(sel)
    msg = f"unknown body region {name!r}: the body has labels {sorted(body.region_labels)} and the geometric fallbacks are {list(GEOMETRIC_REGIONS)}"
    raise InputError(msg)


def region_vertices(body, name: str, normals: np.ndarray) -> tuple[np.ndarray, str]:
    """Vertex indices of a named region.

    Parameters
    ----------
    body : Body
    name : str
        A key of ``body.region_labels`` or one of :data:`GEOMETRIC_REGIONS`.
    normals : (n, 3) float64
        Outward vertex normals (used by some geometric fallbacks).

    Returns
    -------
    indices : (k,) int64
    source : str
        ``"label"``, ``"geometric"`` or, for ``face``, ``"label+geometric"``
        (the label united with the geometric face).
    """
    labels = body.region_labels or {}
    if name in labels:
        idx = np.asarray(labels[name], dtype=np.int64)
        if name == "face":
            # a face label may leave out the eyelids and eye sockets (eyes
            # removed from the mesh); the geometric face closes those gaps
            return np.union1d(idx, _geometric_region(body, name, normals)), "label+geometric"
        return idx, "label"
    return _geometric_region(body, name, normals), "geometric"


def exclusion_mask(body, names: Sequence[str], normals: np.ndarray) -> tuple[np.ndarray, dict]:
    """Vertices with user weight nu = 0.

    Returns
    -------
    excluded : (n,) bool
    sources : dict of str to str
        How each region was found (``label`` or ``geometric``).
    """
    excluded = np.zeros(len(body.vertices), dtype=bool)
    sources = {}
    for name in names:
        idx, src = region_vertices(body, name, normals)
        excluded[idx] = True
        sources[name] = src
    return excluded, sources
