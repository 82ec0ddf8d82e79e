"""Picture sheets: captioned panels in a grid, a title, a colour bar, a table, PNG bytes.

The house style of every seatkit picture (the report's PNGs, ``seatkit body``
and ``seatkit pressure`` pictures, the cage pictures of the benchmarks): a
light grey background, dark text in PIL's default (scalable) font, views of
one size side by side, and a colour bar whose ticks are labelled in the
unit of the values it maps.
"""

from __future__ import annotations

import io
import math

import numpy as np

from seatkit.metrics import TABLE_CAPTION
from seatkit.picture.colour import ColourScale, nice_ticks
from seatkit.picture.raster import to_uint8

__all__ = ["BACKGROUND", "TEXT", "colour_bar", "font", "legend", "png_bytes", "sheet", "to_pil"]

#: Background of every picture, RGB in [0, 1].
BACKGROUND = np.array([0.965, 0.965, 0.975])
#: Text and tick colour, RGB bytes.
TEXT = (30, 30, 30)
#: Colour bar layout, pixels: the strip's width and left edge, the free rows
#: above and below it, the bar's least width.
BAR_STRIP_WIDTH, BAR_STRIP_LEFT, BAR_MARGIN, BAR_WIDTH = 18, 8, 30, 92
#: Sheet layout, pixels: title band, caption band, table line height.
TITLE_HEIGHT, CAPTION_HEIGHT, LINE_HEIGHT = 34, 22, 19


def font(size: int):
    """PIL's default font at ``size`` pixels (scalable; the same on every machine)."""
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def _background_bytes(background) -> tuple[int, int, int]:
    return tuple(int(255 * c) for c in background)


def colour_bar(height: int, scale: ColourScale, low: float, high: float, label: str, *, unit: float = 1.0, background=BACKGROUND):
    """A vertical colour bar (PIL image) for values from ``low`` (bottom) to ``high`` (top).

    Parameters
    ----------
    height : int
        Pixels (the strip leaves :data:`BAR_MARGIN` free above and below).
    scale : ColourScale
    low, high : float
        The values at the ends of the strip, in the values' own unit (Pa ...).
    label : str
        Written above the strip: the unit of the ticks (``kPa``).
    unit : float
        Value of one tick unit in the values' unit (1000 for ticks in kPa of
        values in Pa): ticks are round numbers of ``value / unit``.

    The bar is :data:`BAR_WIDTH` wide, or wider when its label or tick
    labels need it.
    """
    from PIL import Image, ImageDraw

    top, bottom = BAR_MARGIN, height - BAR_MARGIN
    lo, hi = low / unit, high / unit
    ticks = nice_ticks(lo, hi)
    text = font(13)
    tick_x = BAR_STRIP_LEFT + BAR_STRIP_WIDTH
    need = max([text.getlength(label) + 8] + [tick_x + 7 + text.getlength(f"{t:g}") + 4 for t in ticks])
    img = Image.new("RGB", (max(BAR_WIDTH, math.ceil(need)), height), _background_bytes(background))
    t = np.linspace(1.0, 0.0, bottom - top)
    strip = to_uint8(scale.rgb(low + t * (high - low), low, high))
    img.paste(Image.fromarray(np.repeat(strip[:, None, :], BAR_STRIP_WIDTH, axis=1)), (BAR_STRIP_LEFT, top))
    draw = ImageDraw.Draw(img)
    draw.text((4, 6), label, fill=TEXT, font=text)
    for tick in ticks:
        y = bottom - ((tick - lo) / (hi - lo)) * (bottom - top) if hi > lo else bottom
        draw.line([(tick_x, y), (tick_x + 4, y)], fill=TEXT)
        draw.text((tick_x + 7, y - 7), f"{tick:g}", fill=TEXT, font=text)
    return img


def legend(height: int, entries, *, title: str = "", background=BACKGROUND):
    """A column of colour swatches and their names (PIL image), for categories that have no order.

    Parameters
    ----------
    height : int
        Pixels (as high as the views beside it, or more if the entries need it).
    entries : sequence of (str, RGB)
        Names and colours in [0, 1], top to bottom.
    title : str
        Written above the swatches.
    """
    from PIL import Image, ImageDraw

    text = font(13)
    swatch, row = 14, 22
    top = BAR_MARGIN + (row if title else 0)
    need_w = max([text.getlength(title) + 8] + [BAR_STRIP_LEFT + swatch + 8 + text.getlength(name) + 4 for name, _ in entries])
    img = Image.new("RGB", (max(BAR_WIDTH, math.ceil(need_w)), max(height, top + row * len(entries) + BAR_MARGIN)), _background_bytes(background))
    draw = ImageDraw.Draw(img)
    if title:
        draw.text((4, 6), title, fill=TEXT, font=text)
    for i, (name, rgb) in enumerate(entries):
        y = top + i * row
        draw.rectangle([BAR_STRIP_LEFT, y, BAR_STRIP_LEFT + swatch, y + swatch], fill=_background_bytes(rgb), outline=TEXT)
        draw.text((BAR_STRIP_LEFT + swatch + 8, y), name, fill=TEXT, font=text)
    return img


def sheet(title: str, panels, *, colorbar=None, table=None, table_head=("ours", "baseline"), table_caption: str = TABLE_CAPTION,
          columns: int | None = None, background=BACKGROUND):
    """Lay out captioned panels in a grid with a title, an optional colour bar and table.

    Parameters
    ----------
    title : str
        One line (or several, separated by newlines: the title band grows).
    panels : list of (PIL.Image, str)
        Views of one size and their captions.
    colorbar : PIL.Image, optional
        Placed right of the grid, level with the first row's views.
    table : (rows, labels), optional
        Blocks of ``(heading, values of column 1, values of column 2)`` with
        the row ``labels``, drawn under the grid, one block per heading
        (the report's Table 1 per person).
    table_head : tuple of str
        Titles of the value columns (two, or three with a design's own
        column: a shared design's sitters beside their own designs).
    table_caption : str
        Written left of the column titles in each block.
    columns : int, optional
        Panels per row (default all in one row).

    Returns
    -------
    PIL.Image
    """
    from PIL import Image, ImageDraw

    columns = columns or len(panels)
    n_rows = math.ceil(len(panels) / columns)
    panel_w, panel_h = panels[0][0].size
    lines = title.split("\n")
    title_h = TITLE_HEIGHT + (len(lines) - 1) * 22
    caption_h, line_h = CAPTION_HEIGHT, LINE_HEIGHT
    rows, labels = table if table is not None else ([], [])
    table_h = len(rows) * (len(labels) + 2) * line_h + 16 if rows else 0
    grid_w, grid_h = columns * panel_w, n_rows * (panel_h + caption_h)
    width = grid_w + (colorbar.width if colorbar is not None else 0)
    # wide enough for the longest title line (one or two panels under a long title)
    width = max(width, 20 + math.ceil(max(font(17).getlength(line) for line in lines)))
    height = title_h + grid_h + table_h
    if colorbar is not None:
        height = max(height, title_h + caption_h + colorbar.height)
    out = Image.new("RGB", (width, height), _background_bytes(background))
    draw = ImageDraw.Draw(out)
    for i, line in enumerate(lines):
        draw.text((10, 8 + 22 * i), line, fill=TEXT, font=font(17))
    text = font(14)
    for k, (img, caption) in enumerate(panels):
        x = (k % columns) * panel_w
        y = title_h + (k // columns) * (panel_h + caption_h)
        draw.text((x + 10, y + 2), caption, fill=TEXT, font=text)
        out.paste(img, (x, y + caption_h))
    if colorbar is not None:
        out.paste(colorbar, (grid_w, title_h + caption_h))
    # the table: a label column and right-aligned value columns
    y = title_h + grid_h + 8
    bold = font(14)
    col_right = (400, 560, 720)
    for heading, *values in rows:
        draw.text((12, y), heading, fill=TEXT, font=bold)
        y += line_h
        draw.text((28, y), table_caption, fill=TEXT, font=text)
        for x, head in zip(col_right, table_head):
            draw.text((x, y), head, fill=TEXT, font=bold, anchor="ra")
        y += line_h
        for k, lab in enumerate(labels):
            draw.text((28, y), lab, fill=TEXT, font=text)
            for x, column in zip(col_right, values):
                draw.text((x, y), column[k], fill=TEXT, font=text, anchor="ra")
            y += line_h
    return out


def to_pil(image: np.ndarray):
    """A PIL image of a (h, w, 3) float image in [0, 1]."""
    from PIL import Image

    return Image.fromarray(to_uint8(image))


def png_bytes(image) -> bytes:
    """The PNG encoding of a PIL image (zlib level 1: fast, and it releases the GIL)."""
    buf = io.BytesIO()
    image.save(buf, format="PNG", compress_level=1)
    return buf.getvalue()
