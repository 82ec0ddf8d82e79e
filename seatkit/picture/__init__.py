"""One way to draw pictures: a numpy z-buffer rasteriser, colour scales, sheets.

The bottom layer of seatkit's pictures (it imports numpy, PIL and
seatkit.constants only). Every PNG of a body, a pressure field, a cage or a
surface is drawn with it: the report's pictures, ``seatkit body``,
``seatkit pressure``, ``structure.png`` and the documentation's pictures.

- :mod:`.raster`: orthographic views, triangle meshes rasterised with a depth
  buffer (right under self-occlusion), Gouraud-shaded per-vertex colours,
  translucent layers composited by depth;
- :mod:`.colour`: colour scales as data (the report's pressure scale,
  ``magma_r``, ``viridis``) and round tick values;
- :mod:`.sheet`: the house style: captioned panels in a grid, a title, a
  colour bar with ticks in units, a legend of named colours, a table, PNG bytes;
- :mod:`.draw`: lines over a picture (a cage's edges with hidden lines
  removed, a skeleton, a ground line, a scale bar).
"""

from __future__ import annotations

from seatkit.picture.colour import PRESSURE_SCALE, ColourScale, colour_scale, nice_ticks
from seatkit.picture.raster import Frame, Raster, composite, fit_frame, fit_frames, light_vertices, rasterize, to_uint8, view_rotation
from seatkit.picture.sheet import BACKGROUND, TEXT, colour_bar, font, legend, png_bytes, sheet, to_pil

__all__ = [
    "BACKGROUND",
    "PRESSURE_SCALE",
    "TEXT",
    "ColourScale",
    "Frame",
    "Raster",
    "colour_bar",
    "colour_scale",
    "composite",
    "fit_frame",
    "fit_frames",
    "font",
    "legend",
    "light_vertices",
    "nice_ticks",
    "png_bytes",
    "rasterize",
    "sheet",
    "to_pil",
    "to_uint8",
    "view_rotation",
]
