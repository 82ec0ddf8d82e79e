"""The paper's 21-segment link-segment skeleton (Perception Neuron naming).

Segment ``i`` is a rigid body; its *proximal joint* connects it to
``PARENTS[i]``. The root segment (Hips, index 0) has no proximal joint, so
there are 20 joints, and joint ``j`` (``j = 0..19``) is the proximal joint of
segment ``j + 1``: it connects segment ``j + 1`` (the child) with
``PARENTS[j + 1]`` (the parent).
"""

from __future__ import annotations

import numpy as np

#: The 21 segments, in the order every (.., 21) array uses.
SEGMENTS: tuple[str, ...] = (
    "Hips",
    "RightUpLeg",
    "RightLeg",
    "RightFoot",
    "LeftUpLeg",
    "LeftLeg",
    "LeftFoot",
    "Spine",
    "Spine1",
    "Spine2",
    "Spine3",
    "Neck",
    "Head",
    "RightShoulder",
    "RightArm",
    "RightForeArm",
    "RightHand",
    "LeftShoulder",
    "LeftArm",
    "LeftForeArm",
    "LeftHand",
)

N_SEGMENTS = len(SEGMENTS)  # 21
N_JOINTS = N_SEGMENTS - 1  # 20

#: Parent segment index of each segment (-1 for the root).
PARENTS: np.ndarray = np.array(
    [-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 10, 11, 10, 13, 14, 15, 10, 17, 18, 19],
    dtype=np.int64,
)

SEGMENT_INDEX: dict[str, int] = {name: i for i, name in enumerate(SEGMENTS)}


def joint_segments() -> np.ndarray:
    """Return the (parent, child) segment pair of every joint.

    Returns
    -------
    pairs : (20, 2) int64
        ``pairs[j] = (PARENTS[j + 1], j + 1)``.
    """
    child = np.arange(1, N_SEGMENTS, dtype=np.int64)
    return np.stack([PARENTS[child], child], axis=1)


def segment_index(name: str) -> int:
    """Index of a segment by name; raises KeyError listing the valid names."""
    try:
        return SEGMENT_INDEX[name]
    except KeyError:
        msg = f"unknown segment {name!r}; expected one of {', '.join(SEGMENTS)}"
        raise KeyError(msg) from None
