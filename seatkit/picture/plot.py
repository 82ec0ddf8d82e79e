"""Simple data plots in the house style (PIL): the accommodation study's picture.

``accommodation.png`` (:func:`write_accommodation_png`): every sampled person
as a dot at their stature and mass (filled teal: accommodated; orange ring:
not; circles women, squares men), and beside it the share accommodated in
bins of stature and of mass (bars, with the number of people in each bin).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from seatkit.picture.colour import nice_ticks
from seatkit.picture.sheet import BACKGROUND, TEXT, font

__all__ = ["write_accommodation_png"]

YES = (32, 140, 130)
NO = (225, 110, 30)
GRID = (215, 215, 222)
BAR = (70, 110, 170)


class _Axes:
    """A plot box at ``(left, top, width, height)`` pixels mapping data ranges ``xr``, ``yr``."""

    def __init__(self, draw, box, xr, yr):
        self.draw, self.box, self.xr, self.yr = draw, box, xr, yr

    def px(self, x, y):
        left, top, w, h = self.box
        return (
            left + (np.asarray(x, float) - self.xr[0]) / (self.xr[1] - self.xr[0]) * w,
            top + h - (np.asarray(y, float) - self.yr[0]) / (self.yr[1] - self.yr[0]) * h,
        )

    def frame(self, xlabel: str, ylabel: str, xticks, yticks, *, xfmt="{:g}", yfmt="{:g}"):
        left, top, w, h = self.box
        small = font(12)
        for t in xticks:
            x, _ = self.px(t, self.yr[0])
            self.draw.line([(x, top), (x, top + h)], fill=GRID)
            self.draw.text((x, top + h + 4), xfmt.format(t), fill=TEXT, font=small, anchor="ma")
        for t in yticks:
            _, y = self.px(self.xr[0], t)
            self.draw.line([(left, y), (left + w, y)], fill=GRID)
            self.draw.text((left - 5, y), yfmt.format(t), fill=TEXT, font=small, anchor="rm")
        self.draw.rectangle([left, top, left + w, top + h], outline=TEXT)
        self.draw.text((left + w / 2, top + h + 22), xlabel, fill=TEXT, font=font(13), anchor="ma")
        self.draw.text((left, top - 6), ylabel, fill=TEXT, font=font(13), anchor="ld")


def _range(values, pad=0.04):
    lo, hi = float(np.min(values)), float(np.max(values))
    span = max(hi - lo, 1e-6)
    return lo - pad * span, hi + pad * span


def _ticks(r):
    t = nice_ticks(r[0], r[1], 6)
    return [x for x in t if r[0] <= x <= r[1]]


def _share_panel(draw, box, values, ok, edges, xlabel: str, fmt: str):
    """Bars: the share accommodated in each bin of ``values`` (``edges``), with each bin's count."""
    ax = _Axes(draw, box, (edges[0], edges[-1]), (0.0, 1.0))
    ax.frame(xlabel, "share accommodated", _ticks((edges[0], edges[-1])), [0, 0.25, 0.5, 0.75, 1.0], xfmt=fmt, yfmt="{:.0%}")
    which = np.clip(np.digitize(values, edges) - 1, 0, len(edges) - 2)
    for b in range(len(edges) - 1):
        members = which == b
        if not members.any():
            continue
        share = float(ok[members].mean())
        x0, y0 = ax.px(edges[b], share)
        x1, y1 = ax.px(edges[b + 1], 0.0)
        draw.rectangle([x0 + 1, y0, x1 - 1, y1], fill=BAR)
        draw.text(((x0 + x1) / 2, y0 - 2), str(int(members.sum())), fill=TEXT, font=font(10), anchor="md")


def write_accommodation_png(path, rows: list[dict], *, title: str) -> Path:
    """Write the accommodation picture for ``rows`` (``stature`` m, ``mass`` kg, ``sex``, ``accommodated``)."""
    from PIL import Image, ImageDraw

    from seatkit.io import write_bytes_atomic
    from seatkit.picture.sheet import png_bytes

    width, height = 1180, 560
    img = Image.new("RGB", (width, height), tuple(int(255 * c) for c in BACKGROUND))
    draw = ImageDraw.Draw(img)
    draw.text((16, 10), title, fill=TEXT, font=font(17))
    if not rows:
        return write_bytes_atomic(path, png_bytes(img))
    stature = np.array([r["stature"] for r in rows], float)
    mass = np.array([r["mass"] for r in rows], float)
    ok = np.array([bool(r["accommodated"]) for r in rows])
    female = np.array([r["sex"] == "female" for r in rows])
    xr, yr = _range(stature), _range(mass)
    ax = _Axes(draw, (80, 70, 560, 420), xr, yr)
    ax.frame("stature (m)", "mass (kg)", _ticks(xr), _ticks(yr), xfmt="{:.2f}")
    x, y = ax.px(stature, mass)
    radius = 4 if len(rows) <= 400 else 3
    for i in np.argsort(ok):  # the accommodated drawn last, the others stay visible as rings
        r = radius
        box = [x[i] - r, y[i] - r, x[i] + r, y[i] + r]
        shape = draw.ellipse if female[i] else draw.rectangle
        if ok[i]:
            shape(box, fill=YES)
        else:
            shape(box, outline=NO, width=2)
    # legend
    lx, ly = 660, 70
    for k, (label, fill, outline, circle) in enumerate((
        ("accommodated, woman", YES, None, True), ("accommodated, man", YES, None, False),
        ("not accommodated, woman", None, NO, True), ("not accommodated, man", None, NO, False),
    )):
        box = [lx, ly + 18 * k, lx + 9, ly + 18 * k + 9]
        (draw.ellipse if circle else draw.rectangle)(box, fill=fill, outline=outline, width=2)
        draw.text((lx + 16, ly + 18 * k + 5), label, fill=TEXT, font=font(12), anchor="lm")
    s_edges = np.linspace(xr[0], xr[1], 9)
    m_edges = np.linspace(yr[0], yr[1], 9)
    _share_panel(draw, (740, 170, 400, 130), stature, ok, s_edges, "stature (m)", "{:.2f}")
    _share_panel(draw, (740, 380, 400, 110), mass, ok, m_edges, "mass (kg)", "{:.0f}")
    return write_bytes_atomic(path, png_bytes(img))
