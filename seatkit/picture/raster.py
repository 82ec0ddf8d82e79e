"""A small vectorised z-buffer rasteriser: every picture seatkit draws.

Matplotlib draws a 27k-triangle body in about a second per view; the report
needs a dozen views in a fraction of that. This module projects triangle
meshes orthographically, rasterises them with a depth buffer (correct under
self-occlusion, unlike painter's order) and shades them with Gouraud
interpolation of per-vertex colours, all as whole-array numpy operations:

1. every triangle's pixel bounding box is enumerated into one flat array of
   candidate fragments (``np.repeat`` over the box sizes, no Python loop);
2. barycentric coordinates of the pixel centres decide coverage and depth;
3. ``np.maximum.at`` keeps the nearest depth per pixel; the fragments that
   reach it are the visible ones.

The result of step 3 (:class:`Raster`) keeps, per pixel, the visible triangle
and its barycentric coordinates, so a mesh rasterised once can be coloured
many times (importance pressure, contact pressure ...) at the cost of a
gather. Images are (h, w, 3) float arrays in [0, 1]; :func:`to_uint8` and PIL
write them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Frame",
    "Raster",
    "composite",
    "fit_frame",
    "fit_frames",
    "light_vertices",
    "rasterize",
    "to_uint8",
    "view_rotation",
]

#: Direction of the light in camera coordinates (right, up, toward viewer).
LIGHT_DIRECTION = np.array([-0.35, 0.55, 1.0]) / np.linalg.norm([-0.35, 0.55, 1.0])
#: Ambient and diffuse shares of the lighting (they sum to 1).
AMBIENT, DIFFUSE = 0.38, 0.62


def view_rotation(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Rotation from world to camera coordinates for an orthographic view.

    Parameters
    ----------
    azimuth_deg : float
        Camera direction around +Y, degrees: 0 looks at the body's front (the
        camera on +Z), 90 from +X, 180 from behind.
    elevation_deg : float
        Camera height angle above the horizontal, degrees.

    Returns
    -------
    (3, 3) float64
        Rows: screen right, screen up, toward the camera (depth grows toward
        the viewer).
    """
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    toward = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    right = np.cross([0.0, 1.0, 0.0], toward)
    right /= np.linalg.norm(right)
    up = np.cross(toward, right)
    return np.stack([right, up, toward])


def light_vertices(colors: np.ndarray, normals: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Per-vertex colours lit by a headlight (two-sided Lambert).

    Parameters
    ----------
    colors : (n, 3) float64
        Base colours in [0, 1].
    normals : (n, 3) float64
        Unit world normals.
    rotation : (3, 3) float64
        The view (:func:`view_rotation`).

    Returns
    -------
    (n, 3) float64
    """
    lambert = np.abs((normals @ rotation.T) @ LIGHT_DIRECTION)
    return np.asarray(colors, dtype=np.float64) * (AMBIENT + DIFFUSE * lambert)[:, None]


@dataclass(frozen=True)
class Frame:
    """Maps camera coordinates (m) to pixels: a scale and an origin.

    Attributes
    ----------
    rotation : (3, 3) float64
        World to camera (:func:`view_rotation`).
    scale : float
        Pixels per metre.
    left, top : float
        Camera x and y (m) that land on pixel (0, 0)'s corner.
    width, height : int
        Image size in pixels.
    """

    rotation: np.ndarray
    scale: float
    left: float
    top: float
    width: int
    height: int

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (k, 2) and depth (k,) (larger is nearer) of world points (k, 3)."""
        cam = np.asarray(points, dtype=np.float64) @ self.rotation.T
        xy = np.empty((len(cam), 2))
        xy[:, 0] = (cam[:, 0] - self.left) * self.scale
        xy[:, 1] = (self.top - cam[:, 1]) * self.scale
        return xy, cam[:, 2]


def fit_frame(point_sets, rotation: np.ndarray, width: int, height: int, *, margin: float = 0.05, scale: float | None = None) -> Frame:
    """The frame that shows every point of ``point_sets`` centred, with a margin.

    Parameters
    ----------
    point_sets : sequence of (k, 3) float64
        World points that must be visible.
    rotation : (3, 3) float64
        The view.
    width, height : int
        Image size, pixels.
    margin : float
        Fraction of the image left free on each side.
    scale : float, optional
        Pixels per metre; default the largest that fits (pass one to draw
        several views at the same scale).
    """
    cam = np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in point_sets]) @ rotation.T
    lo, hi = cam[:, :2].min(axis=0), cam[:, :2].max(axis=0)
    extent = np.maximum(hi - lo, 1e-9)
    if scale is None:
        scale = float(min(width * (1 - 2 * margin) / extent[0], height * (1 - 2 * margin) / extent[1]))
    centre = 0.5 * (lo + hi)
    return Frame(rotation, scale, centre[0] - 0.5 * width / scale, centre[1] + 0.5 * height / scale, int(width), int(height))


def fit_frames(point_sets, rotations, width: int, height: int, *, margin: float = 0.05) -> list[Frame]:
    """Frames of several views at one scale (the largest at which every view fits).

    A body drawn from the front and from the side is then the same size in
    both, so lengths compare across the views.
    """
    scale = min(fit_frame(point_sets, r, width, height, margin=margin).scale for r in rotations)
    return [fit_frame(point_sets, r, width, height, margin=margin, scale=scale) for r in rotations]


@dataclass(frozen=True)
class Raster:
    """The visible triangle and barycentric coordinates of every pixel.

    Attributes
    ----------
    depth : (h, w) float32
        Camera depth of the visible surface (larger is nearer), ``-inf`` where empty.
    face : (h, w) int64
        Visible triangle, -1 where empty.
    covered : (k,) int64
        Flat indices of the covered pixels.
    corners : (k, 3) int64
        Vertex ids of the visible triangle at each covered pixel.
    bary : (k, 3) float32
        Barycentric coordinates of each covered pixel's centre in that triangle.
    """

    depth: np.ndarray
    face: np.ndarray
    covered: np.ndarray
    corners: np.ndarray
    bary: np.ndarray

    @property
    def mask(self) -> np.ndarray:
        """(h, w) bool: pixels the mesh covers."""
        return self.face >= 0

    def shade(self, vertex_values: np.ndarray) -> np.ndarray:
        """Interpolate per-vertex values (n, c) at the covered pixels.

        Returns
        -------
        (k, c) float32
            One row per covered pixel, in the order of :attr:`covered`.
        """
        vals = np.asarray(vertex_values, dtype=np.float32)
        # weighted sum of the three corner values, one corner at a time, the
        # products formed in place (np.take gathers rows several times faster
        # than indexing does; the same products and sums)
        acc = np.take(vals, self.corners[:, 0], axis=0)
        acc *= self.bary[:, 0, None]
        part = np.take(vals, self.corners[:, 1], axis=0)
        part *= self.bary[:, 1, None]
        acc += part
        np.take(vals, self.corners[:, 2], axis=0, out=part)
        part *= self.bary[:, 2, None]
        acc += part
        return acc


#: Box sizes (pixels) triangles are grouped by; larger boxes round up to a multiple of 32.
_SIZES = np.array([1, 2, 4, 8, 16, 32])


def _round_size(size: np.ndarray) -> np.ndarray:
    """Box sizes rounded up to :data:`_SIZES` (or a multiple of 32 beyond)."""
    idx = np.searchsorted(_SIZES, np.minimum(size, _SIZES[-1]))
    return np.where(size > _SIZES[-1], -(-size // 32) * 32, _SIZES[idx])


def rasterize(frame: Frame, vertices: np.ndarray, faces: np.ndarray, *, cull_back: bool = False) -> Raster:
    """Z-buffer rasterisation of a triangle mesh in one view.

    Parameters
    ----------
    frame : Frame
        View and image size.
    vertices : (n, 3) float64
        World positions, m.
    faces : (m, 3) int64
        Triangles.
    cull_back : bool
        Skip triangles seen from behind (their corners clockwise on screen);
        right for closed meshes whose faces are counter-clockwise from
        outside, such as the body.

    Returns
    -------
    Raster
    """
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    w, h = frame.width, frame.height
    xy, z = frame.project(vertices)
    # per-triangle corner coordinates, (m, 3)
    tx, ty, tz = xy[faces, 0], xy[faces, 1], z[faces]
    ex1, ey1 = tx[:, 1] - tx[:, 0], ty[:, 1] - ty[:, 0]
    ex2, ey2 = tx[:, 2] - tx[:, 0], ty[:, 2] - ty[:, 0]
    # signed doubled area on screen (y points down, so counter-clockwise in the world is negative here)
    area2 = ex1 * ey2 - ex2 * ey1
    keep = np.abs(area2) > 1e-12
    if cull_back:
        keep &= area2 < 0
    # pixel bounding box of each triangle (pixel i covers [i, i+1), centre i + 0.5), clipped to the image
    lo_x = np.minimum(np.minimum(tx[:, 0], tx[:, 1]), tx[:, 2])
    hi_x = np.maximum(np.maximum(tx[:, 0], tx[:, 1]), tx[:, 2])
    lo_y = np.minimum(np.minimum(ty[:, 0], ty[:, 1]), ty[:, 2])
    hi_y = np.maximum(np.maximum(ty[:, 0], ty[:, 1]), ty[:, 2])
    x0 = np.clip(np.ceil(lo_x - 0.5), 0, w).astype(np.int64)
    x1 = np.clip(np.floor(hi_x - 0.5), -1, w - 1).astype(np.int64)
    y0 = np.clip(np.ceil(lo_y - 0.5), 0, h).astype(np.int64)
    y1 = np.clip(np.floor(hi_y - 0.5), -1, h - 1).astype(np.int64)
    bw, bh = x1 - x0 + 1, y1 - y0 + 1
    keep &= (bw > 0) & (bh > 0)
    ids = np.flatnonzero(keep)
    depth = np.full(h * w, -np.inf, np.float32)
    face_img = np.full(h * w, -1, np.int64)
    if ids.size:
        # barycentric l1, l2 and depth are affine in the pixel centre (orthographic view):
        # value = a * (cx - x0) + b * (cy - y0) + c, with (x0, y0) the triangle's box corner
        inv = 1.0 / area2[ids]
        ax, ay = tx[ids, 0], ty[ids, 0]
        ox, oy = x0[ids] + 0.5 - ax, y0[ids] + 0.5 - ay  # first pixel centre relative to corner 0
        a1, b1 = ey2[ids] * inv, -ex2[ids] * inv
        a2, b2 = -ey1[ids] * inv, ex1[ids] * inv
        c1, c2 = a1 * ox + b1 * oy, a2 * ox + b2 * oy
        dz1, dz2 = tz[ids, 1] - tz[ids, 0], tz[ids, 2] - tz[ids, 0]
        az_, bz_ = a1 * dz1 + a2 * dz2, b1 * dz1 + b2 * dz2
        cz_ = tz[ids, 0] + c1 * dz1 + c2 * dz2
        # group triangles by box size, rounded up to a few sizes, so each group is one
        # (k, bh, bw) broadcast; the rounding only adds candidates that fail the tests
        sw, sh = _round_size(bw[ids]), _round_size(bh[ids])
        bx0, by0 = x0[ids], y0[ids]
        room_x, room_y = w - bx0, h - by0  # candidates must stay inside the image
        key = sh * (int(sw.max()) + 1) + sw
        order = np.argsort(key, kind="stable")
        bounds = np.flatnonzero(np.diff(key[order])) + 1
        coef = np.stack([a1, b1, c1, a2, b2, c2, az_, bz_, cz_, room_x, room_y]).astype(np.float32)
        parts = []
        for grp in np.split(order, bounds):
            gw, gh = int(sw[grp[0]]), int(sh[grp[0]])
            gx = np.arange(gw, dtype=np.float32)[None, None, :]
            gy = np.arange(gh, dtype=np.float32)[None, :, None]
            ga1, gb1, gc1, ga2, gb2, gc2, _, _, _, grx, gry = coef[:, grp, None, None]
            l1 = ga1 * gx + gb1 * gy + gc1
            l2 = ga2 * gx + gb2 * gy + gc2
            inside = l1 >= -1e-6  # in place: fewer (k, bh, bw) temporaries
            inside &= l2 >= -1e-6
            inside &= l1 + l2 <= 1.0 + 1e-6
            inside &= gx < grx
            inside &= gy < gry
            # the covered candidates' flat indices, split into (triangle, row, column): cheaper than np.nonzero's
            flat = np.flatnonzero(inside)
            k_i, rest = np.divmod(flat, gh * gw)
            y_i, x_i = np.divmod(rest, gw)
            tri = np.take(grp, k_i)
            # the depth at the covered pixels only, with the same operations as over the box
            fx, fy = np.take(gx.ravel(), x_i), np.take(gy.ravel(), y_i)
            zz = np.take(coef[6], tri) * fx + np.take(coef[7], tri) * fy + np.take(coef[8], tri)
            parts.append((tri, (np.take(by0, tri) + y_i) * w + np.take(bx0, tri) + x_i, np.take(l1, flat), np.take(l2, flat), zz))
        tri = np.concatenate([p[0] for p in parts])
        pix = np.concatenate([p[1] for p in parts])
        l1 = np.concatenate([p[2] for p in parts])
        l2 = np.concatenate([p[3] for p in parts])
        frag_z = np.concatenate([p[4] for p in parts])
        # z-buffer: the nearest depth per pixel, then the fragments that reach it
        np.maximum.at(depth, pix, frag_z)
        win = frag_z >= depth[pix]
        # ties (shared edges) leave one winner per pixel: the last written
        face_img[pix[win]] = np.flatnonzero(win)
    covered = np.flatnonzero(face_img >= 0)
    frag = face_img[covered]  # the winning fragment of each covered pixel
    if ids.size:
        l1, l2 = l1[frag], l2[frag]
        bary = np.stack([1.0 - l1 - l2, l1, l2], axis=1).astype(np.float32, copy=False)
        face_img[covered] = ids[tri[frag]]
    else:
        bary = np.zeros((0, 3), np.float32)
    corners = np.take(faces, face_img[covered], axis=0)
    return Raster(depth.reshape(h, w), face_img.reshape(h, w), covered, corners, bary)


def composite(background, layers) -> np.ndarray:
    """Depth-composite shaded layers over a background.

    Parameters
    ----------
    background : (3,) float
        Background colour in [0, 1].
    layers : sequence of (Raster, (k, 3) float32 colours, alpha float)
        Each mesh's raster, its colours at the covered pixels
        (:meth:`Raster.shade`) and its opacity. Opaque layers hide what is
        behind them; translucent ones are blended, far to near per pixel,
        over the nearest opaque layer behind them.

    Returns
    -------
    (h, w, 3) float32
    """
    layers = list(layers)
    h, w = layers[0][0].depth.shape
    image = np.repeat(np.asarray(background, dtype=np.float32).reshape(1, 3), h * w, axis=0)
    front = np.full(h * w, -np.inf, np.float32)
    # opaque layers by z-buffer
    for raster, colors, alpha in layers:
        if alpha >= 1.0:
            depth = np.take(raster.depth.ravel(), raster.covered)
            nearer = depth > np.take(front, raster.covered)
            pix = raster.covered[nearer]
            _put_rows(image, pix, colors, nearer)
            front[pix] = depth[nearer]
    trans = [layer for layer in layers if layer[2] < 1.0]
    if len(trans) > 1:
        # rank each pixel's translucent layers far to near; blend rank by rank
        depths = np.stack([r.depth.ravel() for r, _, _ in trans])  # (t, h*w), -inf where not covered
        rank = np.argsort(np.argsort(depths, axis=0), axis=0)
    for k in range(len(trans)):
        for t, (raster, colors, alpha) in enumerate(trans):
            depth = raster.depth.ravel()[raster.covered]
            sel = depth > front[raster.covered]
            if len(trans) > 1:
                sel &= rank[t, raster.covered] == k
            elif k > 0:
                continue
            pix = raster.covered[sel]
            _put_rows(image, pix, (1.0 - alpha) * np.take(image, pix, axis=0) + alpha * np.compress(sel, colors, axis=0))
    return image.reshape(h, w, 3)


#: One pixel's three float32 channels as one 12-byte item.
_PIXEL = np.dtype((np.void, 12))


def _put_rows(image: np.ndarray, pix: np.ndarray, rows: np.ndarray, select: np.ndarray | None = None) -> None:
    """``image[pix] = rows[select]`` (``rows`` whole without ``select``) for an (n, 3) float32 image.

    float32 rows are moved as 12-byte items, three times faster than numpy
    assigns (k, 3) rows; the same values, bit for bit. Rows of another type
    are assigned (and converted) as numpy does.
    """
    rows = np.asarray(rows)
    if rows.dtype == np.float32 and rows.ndim == 2 and rows.shape[1] == 3 and image.flags.c_contiguous:
        items = np.ascontiguousarray(rows).view(_PIXEL).ravel()
        image.view(_PIXEL).ravel()[pix] = items if select is None else items[select]
    else:
        image[pix] = rows if select is None else rows[select]


def to_uint8(image: np.ndarray) -> np.ndarray:
    """(h, w, 3) uint8 of a float image in [0, 1]."""
    return (np.clip(image, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
