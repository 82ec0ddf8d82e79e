"""The canonical frame: every posed body turned to face +Z and centred before any fitting.

A capture keeps the heading its person had in the capture room; the
templates are fitted in their own axes (+Y up, the person facing +Z, the
pelvis above the origin). So every body is brought into that frame first,
by a rotation about +Y and a horizontal translation, both rigid:

- **heading**: the body's left-right axis is the sum of the unit vectors
  from the right hip joint to the left one and from the right shoulder
  (``RightArm``) to the left one, each taken horizontally (its vertical part
  dropped, so a tilted line counts for less); the person faces
  ``left x up`` (+X left, +Y up gives +Z). The pelvis alone turns with
  the legs (a person sitting with crossed legs), the shoulders alone with a
  reaching arm; their sum is the trunk's heading. The root's own yaw is not
  used: a capture's root axes are whatever its skeleton's author chose.
  When that axis is nearly vertical (the person lies on the side: its
  horizontal length below :data:`MIN_LATERAL`), the heading is the chest's
  normal ``left x trunk`` seen from above instead.
- **centre**: the midpoint of the hip joints is put above the origin
  (x = z = 0); heights are kept (the body is grounded already).

The design is fitted and exported in this frame; :class:`CanonicalFrame`
records the move so that report.json says what was applied and the
``export_frame: capture`` option (recipe, ``--export-frame capture``)
moves the exported geometry back into the capture's own frame.

Several people (a bench): each person is brought into their own canonical
frame, then placed side by side along +X (or at their ``offset``). A bench's
seats all face one way, so a person captured facing elsewhere is turned to
sit on it; the capture frame of a group is therefore not one frame, and
``export_frame: capture`` is for one person only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from seatkit.model import Body, Pose
from seatkit.skeleton import SEGMENT_INDEX as S

__all__ = ["CAPTURE_FRAME_EXPORTERS", "MIN_LATERAL", "POSE_DECIMALS", "CanonicalFrame", "body_heading", "canonical_frame", "pose_canonical", "result_in_capture_frame", "turned_pose", "rotation_about_y", "to_canonical"]

#: Horizontal length below which the summed left-right axis (at most 2) is
#: taken as vertical (a body lying on its side): the chest's normal gives the heading instead.
MIN_LATERAL = 0.3

#: A body within this of the canonical frame (rad, m) is left bit for bit as it is.
_IDENTITY_TOLERANCE = 1e-9

_UP = np.array([0.0, 1.0, 0.0])


def _horizontal(v: np.ndarray) -> np.ndarray:
    return np.array([v[0], 0.0, v[2]])


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else np.zeros(3)


def rotation_about_y(angle: float) -> np.ndarray:
    """(3, 3) float64 rotation by ``angle`` (rad) about +Y (right-handed: +Z turns towards +X)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def body_heading(body: Body) -> float:
    """The direction a posed body faces, seen from above: rad from +Z towards +X (see the module doc).

    Parameters
    ----------
    body : Body

    Returns
    -------
    float
        ``atan2(forward_x, forward_z)``: 0 for a body facing +Z, pi/2 facing +X.
    """
    j = body.joints
    hips = _unit(j[S["LeftUpLeg"]] - j[S["RightUpLeg"]])
    shoulders = _unit(j[S["LeftArm"]] - j[S["RightArm"]])
    left = _horizontal(hips) + _horizontal(shoulders)
    if np.linalg.norm(left) >= MIN_LATERAL:
        forward = np.cross(left, _UP)
    else:
        # lying on the side: the chest's normal, from the full left-right axis and the trunk
        trunk = body.tips[S["Spine3"]] - j[S["Hips"]]
        forward = _horizontal(np.cross(_unit(hips + shoulders), _unit(trunk)))
    return float(np.arctan2(forward[0], forward[2]))


@dataclass(frozen=True)
class CanonicalFrame:
    """The rigid move that took one posed body from its capture's frame into the template's.

    ``x_canonical = rotation @ x_capture + translation``.

    Attributes
    ----------
    heading : float
        The body's heading in the capture (rad from +Z towards +X, :func:`body_heading`).
    rotation : (3, 3) float64
        Rotation about +Y by ``-heading``.
    translation : (3,) float64
        Horizontal shift putting the hip joints' midpoint above the origin, m.
    """

    heading: float
    rotation: np.ndarray
    translation: np.ndarray

    @property
    def is_identity(self) -> bool:
        """True when the body was left as it was (it faced +Z, centred, already)."""
        return bool(np.array_equal(self.rotation, np.eye(3)) and not self.translation.any())

    def apply(self, points: np.ndarray) -> np.ndarray:
        """(n, 3) points of the capture's frame in the canonical frame."""
        return np.asarray(points, dtype=np.float64) @ self.rotation.T + self.translation

    def inverse_apply(self, points: np.ndarray) -> np.ndarray:
        """(n, 3) points of the canonical frame back in the capture's frame."""
        return (np.asarray(points, dtype=np.float64) - self.translation) @ self.rotation

    def report(self) -> dict:
        """What report.json says of it (degrees for a person to read, metres)."""
        return {
            "capture_heading_deg": float(np.degrees(self.heading)),
            "rotation_about_y_deg": float(np.degrees(-self.heading)),
            "rotation": self.rotation.tolist(),
            "translation_m": self.translation.tolist(),
            "maps": "x_design = rotation @ x_capture + translation",
        }


def canonical_frame(body: Body) -> CanonicalFrame:
    """The move that turns ``body`` to face +Z with its hip joints' midpoint above the origin."""
    heading = body_heading(body)
    if abs(heading) <= _IDENTITY_TOLERANCE:
        heading = 0.0
    rotation = rotation_about_y(-heading) if heading else np.eye(3)
    j = body.joints
    centre = rotation @ (0.5 * (j[S["LeftUpLeg"]] + j[S["RightUpLeg"]]))
    translation = -_horizontal(centre)
    translation[np.abs(translation) <= _IDENTITY_TOLERANCE] = 0.0
    return CanonicalFrame(heading, rotation, translation + 0.0)  # + 0.0: no negative zeros


def moved(body: Body, frame: CanonicalFrame) -> Body:
    """``body`` moved rigidly by ``frame`` (points rotated and shifted)."""
    from dataclasses import replace

    if frame.is_identity:
        return body
    return replace(
        body,
        vertices=frame.apply(body.vertices),
        joints=frame.apply(body.joints),
        tips=frame.apply(body.tips),
        segment_com=frame.apply(body.segment_com),
    )


def to_canonical(body: Body) -> tuple[Body, CanonicalFrame]:
    """``body`` moved rigidly into the canonical frame, and the move (for a body without its pose: ``seatkit poses --check``)."""
    frame = canonical_frame(body)
    return moved(body, frame), frame


#: Decimals (rad) the canonical pose's rotation vectors are rounded to (:func:`pose_canonical`).
POSE_DECIMALS = 9


def pose_canonical(model, rig, pose: Pose) -> tuple[Body, CanonicalFrame]:
    """Pose ``rig`` with ``pose`` in the canonical frame: the body the build fits, and the move from the capture.

    The root's rotation is turned by ``-heading`` about +Y
    (:func:`body_heading` of the body posed as captured) and the body posed
    again; then it is grounded and shifted so that its hip joints' midpoint
    is above the origin. Every rotation vector of that pose is rounded to
    :data:`POSE_DECIMALS` decimals (1 nm at a metre) before posing: the
    same capture turned to any heading then gives the same canonical pose bit
    for bit (its joint rotations, derived through the capture's root, differ
    in their last bits otherwise), so the same design, not one that a
    template's tie-breaks on those bits can change (a design depends on
    such bits: a RANSAC inlier on its threshold, a tie in an ordering).

    Parameters
    ----------
    model : seatkit.interfaces.BodyModel
        Its ``pose(rig, pose, ground=True)`` is used.
    rig : RiggedBody
    pose : Pose

    Returns
    -------
    body : Body
        In the canonical frame, grounded.
    frame : CanonicalFrame
        The move from the body posed as captured (grounded) into ``body``'s frame.
    """
    captured = model.pose(rig, pose, ground=True)
    frame = canonical_frame(captured)
    turned = turned_pose(pose, frame)
    body = model.pose(rig, turned, ground=True)
    j = body.joints
    body = body.translated(-_horizontal(0.5 * (j[S["LeftUpLeg"]] + j[S["RightUpLeg"]])))
    # the move actually made: the capture's hip midpoint onto the canonical one
    centre = lambda b: 0.5 * (b.joints[S["LeftUpLeg"]] + b.joints[S["RightUpLeg"]])  # noqa: E731
    translation = centre(body) - frame.rotation @ centre(captured)
    translation[np.abs(translation) <= _IDENTITY_TOLERANCE] = 0.0
    return body, CanonicalFrame(frame.heading, frame.rotation, translation + 0.0)


def turned_pose(pose: Pose, frame: CanonicalFrame) -> Pose:
    """``pose`` with its root turned by ``frame``'s rotation, rounded, without translation (the pose :func:`pose_canonical` poses)."""
    from scipy.spatial.transform import Rotation

    rotations = np.array(pose.rotations, dtype=np.float64)
    turn = Rotation.from_matrix(frame.rotation)
    rotations[0] = (turn * Rotation.from_rotvec(rotations[0])).as_rotvec()
    return Pose(np.round(rotations, POSE_DECIMALS), np.zeros(3), pose.name)


#: The exporters whose files ``export_frame: capture`` moves into the capture's
#: frame (geometry for other tools). The report's pictures and design.npz
#: (which ``seatkit evaluate`` and ``seatkit serve`` read back) stay in the
#: canonical frame, where the person faces the viewer.
CAPTURE_FRAME_EXPORTERS = frozenset({"usd", "usdc", "obj", "surface", "shell", "body-ply"})


def _mesh_to_capture(mesh, frame: CanonicalFrame):
    from dataclasses import replace

    if mesh is None:
        return None
    return replace(
        mesh,
        vertices=frame.inverse_apply(mesh.vertices),
        plane_points=frame.inverse_apply(mesh.plane_points),
        plane_normals=np.asarray(mesh.plane_normals) @ frame.rotation,
    )


def _surface_to_capture(surface, frame: CanonicalFrame):
    from dataclasses import replace

    if surface is None:
        return None
    return replace(surface, vertices=frame.inverse_apply(surface.vertices), normals=np.asarray(surface.normals) @ frame.rotation)


def result_in_capture_frame(result):
    """A copy of a one-person :class:`~seatkit.model.BuildResult` with its geometry in the capture's frame.

    The bodies, both cages, the surface and the baseline's cage and surface
    are moved by the inverse of ``result.frames[0]``; the figures (metrics,
    pressures) do not depend on the frame and are shared.
    """
    from dataclasses import replace

    frames = result.frames or []
    if len(frames) != 1 or len(result.bodies) != 1:
        msg = f"export_frame: capture needs exactly one person (this build has {len(result.bodies)}); a bench's people are each turned to face +Z"
        raise ValueError(msg)
    frame = frames[0]
    if frame.is_identity:
        return result
    inverse = CanonicalFrame(-frame.heading, frame.rotation.T, -(frame.translation @ frame.rotation))
    baseline = result.baseline
    if baseline is not None:
        baseline = replace(baseline, control_mesh=_mesh_to_capture(baseline.control_mesh, frame), surface=_surface_to_capture(baseline.surface, frame))
    return replace(
        result,
        bodies=[moved(result.bodies[0], inverse)],
        initial_mesh=_mesh_to_capture(result.initial_mesh, frame),
        control_mesh=_mesh_to_capture(result.control_mesh, frame),
        surface=_surface_to_capture(result.surface, frame),
        baseline=baseline,
    )
