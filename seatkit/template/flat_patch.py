"""The flat-patch baseline: what Sit & Relax starts from without this paper.

A flat quad patch under the body at the resolution of the chair cage: a
``rows x cols`` face grid whose outermost vertex ring lies on a ground
rectangle (y = 0) and whose other vertices form a flat grid covering the
ground footprint (x-z bounding box) of the supported body vertices, at the
height of the lowest supported vertex (2 cm at least), i.e. under the body.

Why under the body and not at seat height: a patch at the height of the
buttocks would start 40 cm *inside* the shanks and feet, which the chair
supports too, and the fit's penetration term would then drag it through
the legs; Sit & Relax places its patch below the body and pulls it up. The same ``catmull-clark-fit`` refiner, with the same parameters,
then fits it to the body, so every design can be compared with it side by
side (paper Section 6, Fig. 11, "the method of Leimer et al. applied to a
flat patch serving as the control mesh").

It is a :class:`~seatkit.interfaces.SupportTemplate` written in Python (a
flat grid needs no plane fitting, so it does not go through the YAML
template engine); it lives beside the YAML templates' engine and is
registered, with the refiners it is compared with, by the built-in plugin
``seatkit_refiners``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Mapping, Sequence

import numpy as np

from seatkit.errors import RecipeError, UnsupportedPoseError
from seatkit.model import Body, ControlMesh, PressureField
from seatkit.options import Option, defaults
from seatkit.params import component_params
from seatkit.skeleton import SEGMENT_INDEX, SEGMENTS
from seatkit.template.quad_grid import grid_faces, grid_ring

__all__ = ["FLAT_PATCH_DEFAULTS", "FLAT_PATCH_OPTIONS", "CHAIR_SEGMENTS", "flat_patch_cage", "FlatPatchTemplate"]

#: The body segments the chair template supports (feet, shanks, thighs,
#: hips, lumbar and back rows); the baseline supports the same by default.
CHAIR_SEGMENTS: tuple[str, ...] = (
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
)

#: Options of the ``flat-patch`` template (its ``template_params``; lengths in m).
FLAT_PATCH_OPTIONS: dict[str, Option] = {
    "rows": Option("count", "faces front to back, border rings included (the chair: 7 + 4)", 11, "", 3, 200),
    "cols": Option("count", "faces left to right, border rings included (the chair: 3 + 4)", 7, "", 3, 200),
    "height": Option("number", "height of the flat part; negative: under the body, at the lowest supported vertex (>= min_height)", -1.0, "m", None, 5.0),
    "min_height": Option("number", "lowest flat-part height (keeps the rim off the ground ring)", 0.02, "m", 0.0, 5.0),
    "margin": Option("number", "ground rectangle beyond the footprint on every side", 0.05, "m", 0.0, 5.0),
    "importance_threshold": Option("number", "supported body vertices: importance above this", 0.02, "1", 0.0, 1.0),
    "segments": Option("segments", "supported body segments, by name", list(CHAIR_SEGMENTS)),
}

#: Default parameters of the ``flat-patch`` template (from :data:`FLAT_PATCH_OPTIONS`).
FLAT_PATCH_DEFAULTS: dict[str, Any] = defaults(FLAT_PATCH_OPTIONS)


def flat_patch_cage(
    x_range: tuple[float, float],
    z_range: tuple[float, float],
    height: float,
    *,
    rows: int,
    cols: int,
    margin: float,
) -> ControlMesh:
    """A flat cage at ``height`` over a rectangle, its border ring on the ground.

    Parameters
    ----------
    x_range, z_range : (2,) float
        Footprint covered by the flat part, m.
    height : float
        Height of every vertex but the ground ring, m (> 0).
    rows, cols : int
        Faces along z and x, the border ring included (>= 3 each).
    margin : float
        The ground rectangle extends this far beyond the footprint, m.

    Returns
    -------
    ControlMesh
        ``ground`` and ``fixed`` mark the outer ring; faces point up;
        ``face_labels`` are ``flat`` and ``border``.
    """
    x = np.linspace(x_range[0], x_range[1], cols - 1)
    z = np.linspace(z_range[0], z_range[1], rows - 1)
    # add the ground ring outside the footprint
    x = np.concatenate([[x_range[0] - margin], x, [x_range[1] + margin]])
    z = np.concatenate([[z_range[0] - margin], z, [z_range[1] + margin]])
    zz, xx = np.meshgrid(z, x, indexing="ij")
    ground = grid_ring(rows, cols, 0)
    yy = np.where(ground.reshape(zz.shape), 0.0, height)
    vertices = np.stack([xx, yy, zz], axis=-1).reshape(-1, 3)
    faces = grid_faces(rows, cols)
    border_face = ground[faces].any(axis=1)
    return ControlMesh(
        vertices=vertices,
        faces=faces,
        face_segments=np.full(len(faces), -1, np.int64),
        face_person=np.zeros(len(faces), np.int64),
        face_labels=tuple("border" if b else "flat" for b in border_face),
        vertex_weights=np.where(ground, 0.0, 1.0),
        fixed=ground.copy(),
        ground=ground,
        meta={"template": "flat-patch"},
    )


def _segment_ids(names: Sequence[Any]) -> np.ndarray:
    ids = []
    for k, name in enumerate(names):
        if isinstance(name, str):
            if name not in SEGMENT_INDEX:
                msg = f"flat-patch: segments[{k}]: unknown segment {name!r}; expected one of {', '.join(SEGMENTS)}"
                raise RecipeError(msg)
            ids.append(SEGMENT_INDEX[name])
        elif isinstance(name, (int, np.integer)) and 0 <= int(name) < len(SEGMENTS):
            ids.append(int(name))
        else:
            msg = f"flat-patch: segments[{k}]: expected a segment name, got {name!r}"
            raise RecipeError(msg)
    return np.unique(np.asarray(ids, dtype=np.int64))


class FlatPatchTemplate:
    """The ``flat-patch`` template: a flat grid under the body (the baseline)."""

    name = "flat-patch"
    description = "Flat quad patch under the body at the chair's resolution (Sit & Relax baseline)"
    #: Its parameters (``template_params``); ``segments`` makes a build's
    #: baseline support the same body segments as the design it is compared with.
    parameters = tuple(FLAT_PATCH_OPTIONS)
    options = FLAT_PATCH_OPTIONS

    def bind(self, steps):
        """Itself: the flat patch uses no template steps."""
        return self

    def check_params(self, params) -> None:
        """Check ``template_params`` against :data:`FLAT_PATCH_OPTIONS`."""
        from seatkit.errors import ParamError
        from seatkit.options import check_options

        check_options("template 'flat-patch'", FLAT_PATCH_OPTIONS, params, fail=ParamError)

    def fit(
        self,
        bodies: Sequence[Body],
        pressures: Sequence[PressureField],
        *,
        params: Mapping[str, Any] | None = None,
        seed: int = 0,
    ) -> ControlMesh:
        """Place the flat patch under the supported regions of ``bodies``.

        Parameters
        ----------
        bodies : sequence of Body
        pressures : sequence of PressureField
        params : mapping, optional
            Overrides of :data:`FLAT_PATCH_DEFAULTS`.
        seed : int
            Unused (the patch involves no random choice).

        Returns
        -------
        ControlMesh
            ``meta["supported_segments"]`` lists the supported segment ids,
            which ``catmull-clark-fit`` uses.

        Raises
        ------
        UnsupportedPoseError
            When no body vertex is supported.
        """
        params = dict(params or {})
        if isinstance(params.get("segments"), (list, tuple)):  # the library may give segment ids (a cage's meta)
            params["segments"] = [SEGMENTS[int(s)] if isinstance(s, (int, np.integer)) and 0 <= int(s) < len(SEGMENTS) else s for s in params["segments"]]
        p = component_params("template 'flat-patch'", FLAT_PATCH_OPTIONS, params, where=("template_params",))
        if p["rows"] < 3 or p["cols"] < 3:
            msg = f"flat-patch: rows and cols must be at least 3, got {p['rows']} x {p['cols']}"
            raise RecipeError(msg)
        segs = _segment_ids(p["segments"])
        points = []
        for body, pressure in zip(bodies, pressures):
            dominant = np.argmax(body.weights, axis=1)
            supported = (np.asarray(pressure.importance) > p["importance_threshold"]) & np.isin(dominant, segs)
            points.append(body.vertices[supported])
        pts = np.concatenate(points) if points else np.zeros((0, 3))
        if len(pts) == 0:
            msg = "flat-patch: no supported body vertex to place the patch under"
            raise UnsupportedPoseError(msg, parts=[SEGMENTS[s] for s in segs])
        height = p["height"] if p["height"] >= 0 else float(pts[:, 1].min())
        height = max(height, p["min_height"])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        mesh = flat_patch_cage(
            (float(lo[0]), float(hi[0])),
            (float(lo[2]), float(hi[2])),
            height,
            rows=p["rows"],
            cols=p["cols"],
            margin=p["margin"],
        )
        meta = dict(mesh.meta)
        meta.update({"supported_segments": [int(s) for s in segs], "height": height, "params": p})
        return replace(mesh, meta=meta)
