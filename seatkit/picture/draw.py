"""Lines and points drawn over a rasterised picture, with what hides them.

A wireframe (a cage's edges), a skeleton, a ground line, a scale bar: drawn
with PIL on the image :func:`seatkit.picture.raster.composite` made, in the
:class:`~seatkit.picture.raster.Frame` it was made in. :func:`draw_wire`
reads the depth buffers of the rasters to leave out what a solid hides.
"""

from __future__ import annotations

import math

import numpy as np

from seatkit.picture.raster import Frame

__all__ = ["WIRE_DEPTH_MARGIN", "WIRE_SAMPLES", "draw_dashed_line", "draw_scale_bar", "draw_segments", "draw_wire", "quad_edges"]

#: Points tested along each edge for visibility, and the depth margin, m: a
#: point of an edge lies on its own faces, so it is hidden only when the body
#: or another face is nearer than it by more than the margin.
WIRE_SAMPLES, WIRE_DEPTH_MARGIN = 24, 0.012


def quad_edges(quads) -> np.ndarray:
    """(e, 2) int64 unique edges (sorted pairs) of (f, 4) polygons."""
    quads = np.asarray(quads, dtype=np.int64)
    edges = np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    return np.unique(edges, axis=0)


def draw_wire(image, frame: Frame, vertices, quads, own_depth: np.ndarray, other_depth: np.ndarray, *, colour, hidden_colour) -> None:
    """Draw a polygon mesh's edges and vertices on a PIL image, hidden lines removed.

    Each edge is cut into :data:`WIRE_SAMPLES` pieces. A piece behind a nearer
    face of the mesh itself (``own_depth``, the depth buffer of its raster) is
    left out: the mesh reads as the solid it is, and the edges of its far side
    never cross those of its near side. A piece behind the other solid only
    (``other_depth``, the body) is drawn in ``hidden_colour``, 1 px (it shows
    through); the rest in ``colour``, 2 px. Vertices likewise, as dots.

    Parameters
    ----------
    image : PIL.Image
    frame : Frame
        The frame both depth buffers were rasterised in.
    vertices : (n, 3) float64
    quads : (f, 4) int64
    own_depth, other_depth : (h, w) float32
        :attr:`Raster.depth` of the mesh (triangulated) and of what it holds.
    colour, hidden_colour : RGB bytes
    """
    from PIL import ImageDraw

    edges = quad_edges(quads)
    verts = np.asarray(vertices, dtype=np.float64)
    t = (np.arange(WIRE_SAMPLES + 1) / WIRE_SAMPLES)[None, :, None]
    pts = verts[edges[:, 0]][:, None] * (1 - t) + verts[edges[:, 1]][:, None] * t  # (e, k+1, 3)
    xy, z = frame.project(pts.reshape(-1, 3))
    xy, z = xy.reshape(len(edges), -1, 2), z.reshape(len(edges), -1)
    mid_xy, mid_z = 0.5 * (xy[:, 1:] + xy[:, :-1]), 0.5 * (z[:, 1:] + z[:, :-1])
    px = np.clip(mid_xy[..., 0].astype(np.int64), 0, frame.width - 1)
    py = np.clip(mid_xy[..., 1].astype(np.int64), 0, frame.height - 1)
    by_own = own_depth[py, px] > mid_z + WIRE_DEPTH_MARGIN
    by_other = other_depth[py, px] > mid_z + WIRE_DEPTH_MARGIN
    # runs of pieces of one kind along each edge, each drawn as one straight line:
    # 0 behind the mesh itself (left out), 1 behind the other solid only (light), 2 in front
    kind = np.where(by_own, 0, np.where(by_other, 1, 2))
    change = np.ones(kind.shape, dtype=bool)
    change[:, 1:] = kind[:, 1:] != kind[:, :-1]
    run_edge, run_start = np.nonzero(change)
    same_edge = np.append(run_edge[1:] == run_edge[:-1], False)
    run_end = np.where(same_edge, np.append(run_start[1:], 0), kind.shape[1])  # point index ending the run
    run_kind = kind[run_edge, run_start]
    draw = ImageDraw.Draw(image)
    for wanted, fill, width in ((1, hidden_colour, 1), (2, colour, 2)):  # the light lines first
        for e, a, b in zip(*(x[run_kind == wanted].tolist() for x in (run_edge, run_start, run_end))):
            draw.line([tuple(xy[e, a]), tuple(xy[e, b])], fill=fill, width=width)
    pxy, pz = frame.project(verts)
    ix = np.clip(pxy[:, 0].astype(np.int64), 0, frame.width - 1)
    iy = np.clip(pxy[:, 1].astype(np.int64), 0, frame.height - 1)
    front = own_depth[iy, ix] <= pz + WIRE_DEPTH_MARGIN
    clear = other_depth[iy, ix] <= pz + WIRE_DEPTH_MARGIN
    for (x, y), f, c in zip(pxy.tolist(), front.tolist(), clear.tolist()):
        if f:
            draw.ellipse([x - 2, y - 2, x + 2, y + 2], fill=colour if c else hidden_colour)


def draw_segments(image, frame: Frame, starts, ends, *, colour, width: int = 2, dot_colour=None, dot_radius: float = 2.5) -> None:
    """Straight 3D segments (bones: joint -> tip) on top of a picture, dots at their starts."""
    from PIL import ImageDraw

    draw = ImageDraw.Draw(image)
    a, _ = frame.project(np.asarray(starts, dtype=np.float64).reshape(-1, 3))
    b, _ = frame.project(np.asarray(ends, dtype=np.float64).reshape(-1, 3))
    for p, q in zip(a.tolist(), b.tolist()):
        draw.line([tuple(p), tuple(q)], fill=colour, width=width)
    if dot_colour is not None:
        r = dot_radius
        for x, y in a.tolist():
            draw.ellipse([x - r, y - r, x + r, y + r], fill=dot_colour)


def draw_dashed_line(image, y: float, *, colour, dash: int = 6, gap: int = 4) -> None:
    """A horizontal dashed line across the image at pixel row ``y`` (a ground line)."""
    from PIL import ImageDraw

    draw = ImageDraw.Draw(image)
    for x in range(0, image.width, dash + gap):
        draw.line([(x, y), (min(x + dash, image.width - 1), y)], fill=colour, width=1)


def draw_scale_bar(image, frame: Frame, *, colour, font, fraction: float = 0.25) -> float:
    """A horizontal bar of a round length (about ``fraction`` of the width) at the bottom left, labelled in m or cm.

    Returns the length drawn, m.
    """
    from PIL import ImageDraw

    target = fraction * frame.width / frame.scale
    power = 10.0 ** math.floor(math.log10(target))
    length = max(s * power for s in (1, 2, 5) if s * power <= target)  # the longest round length up to the target
    draw = ImageDraw.Draw(image)
    x0, y = 10, image.height - 12
    x1 = x0 + length * frame.scale
    draw.line([(x0, y), (x1, y)], fill=colour, width=2)
    for x in (x0, x1):
        draw.line([(x, y - 4), (x, y + 4)], fill=colour, width=1)
    label = f"{length * 100:g} cm" if length < 1.0 else f"{length:g} m"
    draw.text((x0, y - 20), label, fill=colour, font=font)
    return length
