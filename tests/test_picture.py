"""seatkit.picture and the pictures drawn with it (body, cage): what a picture must show.

The pictures are read back as pixels: the body covers the pixels its
outline covers, a vertex at value v has the colour of v on the colour bar
(times the lighting), the nearer of two parts hides the farther in either
drawing order, the colour bar reaches the largest value shown, and the same
input gives the same bytes.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from seatkit import picture as pic
from seatkit.body.render import SCALE_BAND, render_body
from seatkit.picture import raster as rs
from seatkit.picture.sheet import BAR_MARGIN, BAR_STRIP_LEFT, BAR_STRIP_WIDTH, CAPTION_HEIGHT, TITLE_HEIGHT


def _grid(nx: int, ny: int, x0, x1, y0, y1, z: float):
    """A flat grid facing +Z (counter-clockwise seen from +Z): vertices, triangles."""
    xs, ys = np.linspace(x0, x1, nx), np.linspace(y0, y1, ny)
    X, Y = np.meshgrid(xs, ys)
    v = np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], axis=1)
    i = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
    return v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def _box(lo, hi):
    """A closed axis-aligned box, faces counter-clockwise from outside."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0], [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]])
    quads = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5], [0, 4, 7, 3]]
    f = np.array([t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])])
    return v, f


def _read(png, points, width: int, view=(0.0, 0.0)):
    """The sheet's pixels (int), the row where the first panel starts and the frame it was drawn in.

    render_body's panels are ``width`` wide, drawn at the scale that fits a
    1.25 times higher panel, and cropped to the height the views need.
    """
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    top = TITLE_HEIGHT + CAPTION_HEIGHT
    rot = rs.view_rotation(*view)
    scale = rs.fit_frame([points], rot, width, round(1.25 * width)).scale
    frame = rs.fit_frame([points], rot, width, img.shape[0] - top - SCALE_BAND, scale=scale)
    return img, top, dataclasses.replace(frame, height=frame.height + SCALE_BAND)


BG = np.round(pic.BACKGROUND * 255).astype(int)


def test_the_body_covers_the_pixels_of_its_outline(tmp_path):
    """A box seen from the front fills the rectangle its corners project to, and nothing else."""
    v, f = _box((-0.2, 0.0, -0.1), (0.3, 1.2, 0.1))
    out = render_body(SimpleNamespace(vertices=v, faces=f), tmp_path / "box.png", views=("front",), show_ground=False, dpi=100, panel_size=4)
    width = 400
    img, top, frame = _read(out, v, width)
    panel = img[top : top + frame.height, :width]
    (x0, y0), (x1, y1) = frame.project(np.array([[-0.2, 1.2, 0.1], [0.3, 0.0, 0.1]]))[0]
    yy, xx = np.mgrid[0 : frame.height, 0:width] + 0.5
    inside = (xx > x0) & (xx < x1) & (yy > y0) & (yy < y1)
    body = np.any(np.abs(panel - BG) > 3, axis=2)
    assert not inside[-SCALE_BAND:].any()  # the band of the scale bar, under the view
    body[-SCALE_BAND:, :] = False
    assert body[inside].all()
    assert not body[~inside].any()
    # the box is 0.5 m wide: its outline spans 0.5 m at the frame's scale, within a pixel
    cols = np.flatnonzero(body.any(axis=0))
    assert abs((cols[-1] - cols[0] + 1) - 0.5 * frame.scale) <= 1.0


def test_a_vertex_is_drawn_in_the_colour_of_its_value_on_the_bar(tmp_path):
    """Scalars rising left to right on a flat grid facing the camera: the pixel at each vertex is
    the bar's colour at that value times the headlight's shade of a face seen straight on."""
    v, f = _grid(11, 11, -0.5, 0.5, 0.0, 1.0, 0.0)
    values = 2000.0 * (v[:, 0] + 0.5)  # 0 .. 2000 Pa
    out = render_body(SimpleNamespace(vertices=v, faces=f), tmp_path / "ramp.png", scalars=values, cmap="pressure", views=("front",),
                      show_ground=False, scalar_label="Pa", dpi=100, panel_size=4)
    img, top, frame = _read(out, v, 400)
    shade = rs.AMBIENT + rs.DIFFUSE * abs(rs.LIGHT_DIRECTION[2])  # the normal is the view direction
    # the bar: its strip spans 0 (bottom) .. 2000 Pa (top, the largest value shown: nothing clipped)
    strip_x = 400 + BAR_STRIP_LEFT + BAR_STRIP_WIDTH // 2
    strip_top, strip_bottom = top + BAR_MARGIN, top + frame.height - BAR_MARGIN
    scale = pic.colour_scale("pressure")
    for k in (12, 14, 17, 20, 50, 60, 80, 100, 108):  # interior vertices of the middle row
        xy, _ = frame.project(v[k : k + 1])
        x, y = (xy[0] + 0.5).astype(int)
        pixel = img[top + y, x]
        want = scale.rgb(values[k : k + 1], 0.0, 2000.0)[0] * 255.0
        assert np.abs(pixel - want * shade).max() <= 3.0, (k, pixel, want * shade)
        # the bar shows the same colour (unshaded) at the height of that value
        row = int(round(strip_bottom - values[k] / 2000.0 * (strip_bottom - strip_top)))
        assert np.abs(img[min(row, strip_bottom - 1), strip_x] - want).max() <= 6.0
    assert np.abs(img[strip_top, strip_x] - scale.rgb([2000.0], 0, 2000)[0] * 255).max() <= 6.0


def test_categories_are_drawn_in_their_own_colours_and_named_in_the_legend(tmp_path):
    """Per-vertex colours (regions): each half of a grid facing the camera is its colour times the
    headlight's shade, and the legend beside the view shows each colour's swatch."""
    v, f = _grid(11, 11, -0.5, 0.5, 0.0, 1.0, 0.0)
    red, blue = (0.84, 0.15, 0.16), (0.12, 0.47, 0.71)
    colours = np.where((v[:, 0] < 0)[:, None], red, blue)
    out = render_body(SimpleNamespace(vertices=v, faces=f), tmp_path / "regions.png", colors=colours,
                      legend=[("left", red), ("right", blue)], views=("front",), show_ground=False, dpi=100, panel_size=4)
    img, top, frame = _read(out, v, 400)
    shade = rs.AMBIENT + rs.DIFFUSE * abs(rs.LIGHT_DIRECTION[2])
    for point, colour in (((-0.3, 0.5, 0.0), red), ((0.3, 0.5, 0.0), blue)):
        (x, y), = frame.project(np.array([point]))[0]
        assert np.abs(img[top + int(y), int(x)] - np.array(colour) * 255 * shade).max() <= 3.0
    legend = img[:, 400:]
    for colour in (red, blue):  # an unshaded swatch of each colour
        assert (np.abs(legend - np.round(np.array(colour) * 255)).max(axis=2) <= 1).sum() >= 100
    with pytest.raises(ValueError, match="not both"):
        render_body(SimpleNamespace(vertices=v, faces=f), tmp_path / "x.png", colors=colours, scalars=v[:, 0])
    with pytest.raises(ValueError, match="colors must be"):
        render_body(SimpleNamespace(vertices=v, faces=f), tmp_path / "x.png", colors=colours[:3])
    assert not (tmp_path / "x.png").exists()


def test_the_nearer_part_hides_the_farther_in_either_drawing_order(tmp_path):
    near_v, near_f = _grid(2, 2, -0.1, 0.3, 0.2, 0.6, 0.2)
    far_v, far_f = _grid(2, 2, -0.3, 0.1, 0.0, 0.4, 0.0)
    values = np.r_[np.ones(4), np.zeros(4)]
    pixels = []
    for order in ((near_v, near_f, far_v, far_f), (far_v, far_f, near_v, near_f)):
        a_v, a_f, b_v, b_f = order
        mesh = SimpleNamespace(vertices=np.concatenate([a_v, b_v]), faces=np.concatenate([a_f, b_f + 4]))
        vals = values if a_v is near_v else values[::-1]
        out = render_body(mesh, tmp_path / "overlap.png", scalars=vals, cmap=[(0.0, 0.0, 1.0), (1.0, 0.0, 0.0)], views=("front",), show_ground=False)
        img, top, frame = _read(out, mesh.vertices, 440)
        (x, y), = frame.project(np.array([[0.0, 0.3, 0.2]]))[0]  # inside both squares
        pixel = img[top + int(y), int(x)]
        assert pixel[0] > 100 and pixel[2] < 10, pixel  # red: the near square (value 1)
        pixels.append(pixel)
    assert np.array_equal(pixels[0], pixels[1])


def test_pictures_are_deterministic_and_refuse_bad_input(tmp_path):
    v, f = _box((0, 0, 0), (0.4, 0.9, 0.3))
    body = SimpleNamespace(vertices=v, faces=f, joints=np.zeros((21, 3)) + 0.2, tips=np.zeros((21, 3)) + 0.5)
    a = render_body(body, tmp_path / "a.png", scalars=v[:, 1], show_skeleton=True, views=("front", (30, 20))).read_bytes()
    b = render_body(body, tmp_path / "b.png", scalars=v[:, 1], show_skeleton=True, views=("front", (30, 20))).read_bytes()
    assert a == b
    with pytest.raises(ValueError, match="scalars must be"):
        render_body(body, tmp_path / "c.png", scalars=np.zeros(3))
    with pytest.raises(ValueError, match="unknown colour map 'jet'"):
        render_body(body, tmp_path / "c.png", scalars=v[:, 1], cmap="jet")
    with pytest.raises(ValueError, match="unknown view 'up'"):
        render_body(body, tmp_path / "c.png", views=("up",))
    assert not (tmp_path / "c.png").exists()


def test_colour_bar_ticks_cover_the_range_in_round_steps():
    assert pic.nice_ticks(0.0, 7.4).tolist() == [0.0, 2.0, 4.0, 6.0]
    assert pic.nice_ticks(-3.0, 12.0).tolist() == [0.0, 5.0, 10.0]
    assert pic.nice_ticks(0.0, 0.0).tolist() == [0.0]
    t = pic.nice_ticks(0.013, 0.052)
    assert t[0] >= 0.013 - 1e-12 and t[-1] <= 0.052 + 1e-12 and len(t) >= 3


def test_colour_scales_are_matplotlibs_and_plotlys():
    from matplotlib import colormaps
    import plotly.colors as pc

    x = np.linspace(0, 1, 256)
    for name in ("viridis", "magma_r", "magma", "viridis_r"):
        want = colormaps[name](np.arange(256))[:, :3]
        got = pic.colour_scale(name).rgb(x, 0.0, 1.0)
        assert np.abs(got - want).max() <= 0.5 / 255 + 1e-12, name
    plotly = pic.ColourScale.from_hex(pc.sequential.Magma, reverse=True)
    assert np.array_equal(pic.PRESSURE_SCALE.colours, plotly.colours)


def test_cage_picture_shows_supporting_and_structural_faces(tmp_path):
    from seatkit.template.render import SUPPORT_RGB, render_cage

    quads = np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
    cage = SimpleNamespace(
        vertices=np.array([[-0.6, 0, 0], [-0.1, 0, 0], [-0.1, 0.5, 0], [-0.6, 0.5, 0], [0.1, 0, 0], [0.6, 0, 0], [0.6, 0.5, 0], [0.1, 0.5, 0]], float),
        faces=quads,
        face_segments=np.array([3, -1]),
    )
    bv, bf = _box((-0.05, 0.6, -0.05), (0.05, 0.7, 0.05))
    out = render_cage(cage, [SimpleNamespace(vertices=bv, faces=bf)], tmp_path / "cage.png", views=("front",))
    img = np.asarray(Image.open(out).convert("RGB")).astype(int)
    frame = rs.fit_frames([cage.vertices, bv], [rs.view_rotation(0, 0)], round(4.2 * 90), round(4.4 * 90))[0]
    top = TITLE_HEIGHT + CAPTION_HEIGHT
    (xs, ys), (xt, yt) = frame.project(np.array([[-0.35, 0.25, 0.0], [0.35, 0.25, 0.0]]))[0]
    support, structure = img[top + int(ys), int(xs)], img[top + int(yt), int(xt)]
    assert support[2] > support[0] + 30  # blue
    assert abs(int(structure[0]) - int(structure[2])) < 20 and np.all(structure < BG - 10)  # grey, darker than the background
    assert SUPPORT_RGB[2] > SUPPORT_RGB[0]
    with pytest.raises(ValueError, match="unknown view 'under'"):
        render_cage(cage, [], tmp_path / "x.png", views=("under",))
