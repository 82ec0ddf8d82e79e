"""Preview pictures of a triangle mesh (a body), optionally coloured by a scalar.

Drawn with :mod:`seatkit.picture` (the numpy z-buffer of every seatkit
picture: right where one part of the body hides another, and fast on a
27k-triangle body), headless anywhere. Vertex colours are Gouraud-shaded by
a headlight; a per-vertex scalar (a region mask, a weight, a pressure) is
interpolated across each triangle and coloured through a colour scale,
with a colour bar in the scalar's unit. Each panel carries a scale bar
(lengths, m); all views are drawn at one scale.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Sequence

import numpy as np

from seatkit import picture as pic
from seatkit.picture import draw as pic_draw
from seatkit.geometry.normals import vertex_normals

__all__ = ["VIEWS", "render_body", "view_axes"]

#: Camera of each named view: (screen right, screen up, towards the viewer),
#: unit vectors in world axes (+Y up, body facing +Z).
VIEWS: dict[str, tuple[tuple[float, float, float], ...]] = {
    "front": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "back": ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    # seen from the body's right-hand side (-X): the body faces screen right
    "side": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0)),
    "left": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)),
    # from above, the body's front at the bottom of the picture
    "top": ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "bottom": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)),
}


def view_axes(view: str | Sequence[float]) -> np.ndarray:
    """Camera axes of a view.

    Parameters
    ----------
    view : str or (azimuth_deg, elevation_deg)
        A name of :data:`VIEWS`, or azimuth about +Y from the front (degrees,
        positive turns towards the body's left) and elevation above the
        horizon (degrees).

    Returns
    -------
    axes : (3, 3) float64
        Rows: screen right, screen up, towards the viewer.
    """
    if isinstance(view, str):
        try:
            return np.array(VIEWS[view], dtype=np.float64)
        except KeyError:
            msg = f"unknown view {view!r}; expected one of {', '.join(VIEWS)} or (azimuth, elevation) in degrees"
            raise ValueError(msg) from None
    az, el = np.radians(np.asarray(view, dtype=np.float64))
    toward = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    right = np.cross([0.0, 1.0, 0.0], toward)
    right /= np.linalg.norm(right)
    up = np.cross(toward, right)
    return np.stack([right, up, toward])


#: Colours of the overlays: bones, joints, the ground line, the scale bar (RGB bytes).
BONE_RGB, JOINT_RGB, GROUND_RGB, SCALE_BAR_RGB = (0, 0, 0), (220, 20, 20), (100, 100, 100), (60, 60, 60)
#: Height of the band under each view that holds its scale bar, pixels.
SCALE_BAND = 34


def _caption(view) -> str:
    return view if isinstance(view, str) else f"az {view[0]:g}, el {view[1]:g}"


def render_body(
    body,
    path,
    *,
    scalars=None,
    views: Sequence = ("front", "side"),
    cmap="viridis",
    title: str | None = None,
    clim: tuple[float, float] | None = None,
    scalar_label: str = "",
    show_skeleton: bool = False,
    show_ground: bool = True,
    panel_size: float = 4.0,
    dpi: int = 110,
    base_color=(0.82, 0.70, 0.60),
    colors=None,
    legend=None,
) -> Path:
    """Draw a mesh from one or more views into a PNG.

    Parameters
    ----------
    body : Body, RiggedBody or any object with ``vertices`` (n, 3) and ``faces`` (m, 3)
        If it has ``joints`` and ``tips`` (21, 3) they can be drawn.
    path : str or Path
        Output PNG (written atomically).
    scalars : (n,) array_like, optional
        Per-vertex values, interpolated across each triangle; a pixel is
        drawn in the colour of its value on the colour bar (times the
        lighting). NaN values are drawn in the base colour.
    views : sequence
        View names (:data:`VIEWS`) or (azimuth, elevation) pairs in degrees.
    cmap : str, ColourScale or sequence of RGB
        Colour scale for ``scalars`` (:func:`seatkit.picture.colour_scale`:
        ``viridis``, ``viridis_r``, ``magma``, ``magma_r``, ``pressure``, or
        colours in [0, 1] spaced evenly from the low end to the high end).
    title : str, optional
    clim : (float, float), optional
        Colour range; default the finite range of ``scalars`` (nothing
        clipped).
    scalar_label : str
        Colour bar label (the unit of its ticks).
    show_skeleton : bool
        Draw the bones (joint -> tip) and joints on top.
    show_ground : bool
        Draw the ground line y = 0 in views whose up is +Y.
    panel_size : float
        Inches per view panel (with ``dpi``: ``panel_size * dpi`` pixels
        wide, at most 1.25 times that high: as high as the views need,
        and a band for the scale bar).
    dpi : int
    base_color : RGB tuple
        Colour of the mesh without scalars.
    colors : (n, 3) array_like, optional
        Per-vertex RGB in [0, 1], for categories (regions, segments) that
        have no order and so no colour bar; not with ``scalars``.
    legend : sequence of (str, RGB), optional
        Names of the colours, drawn right of the views in place of a
        colour bar.

    Returns
    -------
    Path
        ``path``.
    """
    from seatkit.io import write_bytes_atomic

    vertices = np.asarray(body.vertices, dtype=np.float64)
    faces = np.asarray(body.faces, dtype=np.int64)
    rotations = [view_axes(view) for view in views]  # refuses an unknown view before any work
    values = scale = None
    lo = hi = 0.0
    base = np.asarray(base_color if colors is None else colors, dtype=np.float64)
    if colors is not None:
        if scalars is not None:
            msg = "give scalars (a colour scale) or colors (per-vertex RGB), not both"
            raise ValueError(msg)
        if base.shape != vertices.shape:
            msg = f"colors must be ({len(vertices)}, 3), got {base.shape}"
            raise ValueError(msg)
    base = np.broadcast_to(base, vertices.shape)
    if scalars is not None:
        values = np.asarray(scalars, dtype=np.float64)
        if values.shape != (len(vertices),):
            msg = f"scalars must be ({len(vertices)},), got {values.shape}"
            raise ValueError(msg)
        scale = pic.colour_scale(cmap)
        finite = values[np.isfinite(values)]
        lo, hi = clim if clim is not None else ((float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0))
        if hi <= lo:
            hi = lo + 1.0
    width, height = round(panel_size * dpi), round(1.25 * panel_size * dpi)
    fit = [vertices]
    if show_ground:  # the ground line in the picture too
        fit.append(np.array([[vertices[:, 0].min(), 0.0, vertices[:, 2].min()], [vertices[:, 0].max(), 0.0, vertices[:, 2].max()]]))
    frames = pic.fit_frames(fit, rotations, width, height)
    # panels no higher than the views need (a row of standing bodies is wide and low)
    margin = 0.05
    need = max(np.ptp(np.concatenate(fit) @ r[1]) for r in rotations) * frames[0].scale / (1 - 2 * margin)
    if need + 2 < height:
        height = int(np.ceil(need)) + 2
        frames = [pic.fit_frame(fit, r, width, height, margin=margin, scale=frames[0].scale) for r in rotations]
    # a band below the views for the scale bar, clear of the feet and the ground line
    height += SCALE_BAND
    frames = [replace(f, height=height) for f in frames]
    normals = vertex_normals(vertices, faces)
    text = pic.font(13)
    panels = []
    for view, frame in zip(views, frames):
        raster = pic.rasterize(frame, vertices, faces)
        if values is None:
            colours = raster.shade(pic.light_vertices(base, normals, frame.rotation))
        else:
            light = raster.shade(pic.light_vertices(np.ones_like(vertices), normals, frame.rotation))
            value = raster.shade(values[:, None])[:, 0]
            rgb = scale.rgb(value, lo, hi)
            rgb[~np.isfinite(value)] = base_color
            colours = (rgb * light).astype(np.float32)
        image = pic.to_pil(pic.composite(pic.BACKGROUND, [(raster, colours, 1.0)]))
        if show_ground and frame.rotation[1, 1] > 0.999:
            pic_draw.draw_dashed_line(image, frame.project(np.zeros((1, 3)))[0][0, 1], colour=GROUND_RGB)
        if show_skeleton and hasattr(body, "joints") and hasattr(body, "tips"):
            pic_draw.draw_segments(image, frame, body.joints, body.tips, colour=BONE_RGB, dot_colour=JOINT_RGB)
        pic_draw.draw_scale_bar(image, frame, colour=SCALE_BAR_RGB, font=text)
        panels.append((image, _caption(view)))
    bar = pic.colour_bar(height, scale, lo, hi, scalar_label) if scale is not None else None
    if legend is not None:
        bar = pic.legend(height, legend, title=scalar_label)
    sheet = pic.sheet(title or "", panels, colorbar=bar)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, pic.png_bytes(sheet))
    return path
