"""Colour scales of seatkit's pictures and their tick values.

A :class:`ColourScale` is a piecewise-linear map from [0, 1] to RGB, given by
its stops; :meth:`ColourScale.rgb` maps values between a low and a high end
onto it (values outside are drawn at the nearest end, so a picture that
compares fields passes the largest of them as ``high``: nothing is clipped).

The scales are data, not imports: the report's pressure scale is plotly's
``Magma`` (ten stops, reversed: light at zero, dark at the peak), the
256-entry ``magma_r`` and ``viridis`` maps are matplotlib's, as bytes, so a
picture needs neither plotly nor matplotlib (tests compare them with both).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["MAGMA_R_BYTES", "PRESSURE_SCALE", "VIRIDIS_BYTES", "ColourScale", "colour_scale", "nice_ticks"]

#: plotly's ``Magma`` scale (plotly.colors.sequential.Magma), dark to light.
PLOTLY_MAGMA = ("#000004", "#180f3d", "#440f76", "#721f81", "#9e2f7f", "#cd4071", "#f1605d", "#fd9668", "#feca8d", "#fcfdbf")

#: matplotlib's colour map "magma_r" (magma reversed) as its 256 RGB bytes.
MAGMA_R_BYTES = bytes.fromhex(
    "fcfdbffcfbbdfcf9bbfcf7b9fcf6b8fcf4b6fcf2b4fcf0b2fceeb0fcecaefdebacfde9aafde7a9fde5a7fde3a5fde2a3"
    "fde0a1fddea0fddc9efdda9cfed89afed799fed597fed395fed194fecf92fecd90fecc8ffeca8dfec88cfec68afec488"
    "fec287fec185febf84febd82febb81feb97ffeb77efeb67cfeb47bfeb27afeb078feae77feac76feaa74fea973fea772"
    "fea571fea36ffea16efe9f6dfe9d6cfd9b6bfd9a6afd9869fd9668fd9467fd9266fc9065fc8e64fc8c63fc8a62fc8961"
    "fb8761fb8560fb835ffa815ffa7f5efa7d5ef97b5df9795df9785df8765cf8745cf7725cf7705cf66e5cf66c5cf56b5c"
    "f4695cf4675cf3655cf2645cf2625df1605df05f5eef5d5eee5b5eed5a5fec5860eb5760ea5661e95462e85362e75263"
    "e55064e44f64e34e65e24d66e04c67df4a68de4968dc4869db476ad9466bd8456cd6456cd5446dd3436ed2426fd0416f"
    "cf4070cd4071cc3f71ca3e72c83e73c73d73c53c74c43c75c23b75c03a76bf3a77bd3977bc3978ba3878b83779b73779"
    "b5367ab3367ab2357bb0357bae347bad347cab337caa337da8327da6317da5317ea3307ea1307ea02f7f9e2f7f9c2e7f"
    "9b2e7f992d80982d80962c80942c80932b80912b81902a818e2a818c29818b2981892881882781862781842681832681"
    "8125818025827e24827c23827b2382792282782281762181752181732081721f81701f816e1e816d1d816b1d816a1c81"
    "681c81671b80651a80641a806219806018805f187f5d177f5c167f5a167e59157e57157e56147d54137d52137c51127c"
    "4f127b4e117b4c117a4a1079491078471078451077440f76420f75400f743f0f723d0f713b0f70390f6e38106c36106b"
    "3410693310673111652f11632d11612c115f2a115c29115a27125825125524125322115021114e20114b1e11491d1147"
    "1c10441a104219103f180f3d160f3b150e38140e36130d34120d31110c2f100b2d0e0b2b0d0a290c09260b09240a0822"
    "09072008071e07061c06051a06051805041604041403031203030f02020d02020b020109010108010106010005000004"
)

#: matplotlib's colour map "viridis" as its 256 RGB bytes.
VIRIDIS_BYTES = bytes.fromhex(
    "44015444025645045745055946075a46085c460a5d460b5e470d60470e61471063471164471365481467481668481769"
    "48186a481a6c481b6d481c6e481d6f481f70482071482173482374482475482576482677482878482979472a7a472c7a"
    "472d7b472e7c472f7d46307e46327e46337f463480453581453781453882443983443a83443b84433d84433e85423f85"
    "4240864241864142874144874045884046883f47883f48893e49893e4a893e4c8a3d4d8a3d4e8a3c4f8a3c508b3b518b"
    "3b528b3a538b3a548c39558c39568c38588c38598c375a8c375b8d365c8d365d8d355e8d355f8d34608d34618d33628d"
    "33638d32648e32658e31668e31678e31688e30698e306a8e2f6b8e2f6c8e2e6d8e2e6e8e2e6f8e2d708e2d718e2c718e"
    "2c728e2c738e2b748e2b758e2a768e2a778e2a788e29798e297a8e297b8e287c8e287d8e277e8e277f8e27808e26818e"
    "26828e26828e25838e25848e25858e24868e24878e23888e23898e238a8d228b8d228c8d228d8d218e8d218f8d21908d"
    "21918c20928c20928c20938c1f948c1f958b1f968b1f978b1f988b1f998a1f9a8a1e9b8a1e9c891e9d891f9e891f9f88"
    "1fa0881fa1881fa1871fa28720a38620a48621a58521a68522a78522a88423a98324aa8325ab8225ac8226ad8127ad81"
    "28ae8029af7f2ab07f2cb17e2db27d2eb37c2fb47c31b57b32b67a34b67935b77937b87838b9773aba763bbb753dbc74"
    "3fbc7340bd7242be7144bf7046c06f48c16e4ac16d4cc26c4ec36b50c46a52c56954c56856c66758c7655ac8645cc863"
    "5ec96260ca6063cb5f65cb5e67cc5c69cd5b6ccd5a6ece5870cf5773d05675d05477d1537ad1517cd2507fd34e81d34d"
    "84d44b86d54989d5488bd6468ed64590d74393d74195d84098d83e9bd93c9dd93ba0da39a2da37a5db36a8db34aadc32"
    "addc30b0dd2fb2dd2db5de2bb8de29bade28bddf26c0df25c2df23c5e021c8e020cae11fcde11dd0e11cd2e21bd5e21a"
    "d8e219dae319dde318dfe318e2e418e5e419e7e419eae51aece51befe51cf1e51df4e61ef6e620f8e621fbe723fde725"
)


@dataclass(frozen=True)
class ColourScale:
    """A piecewise-linear colour scale.

    Attributes
    ----------
    positions : (s,) float64
        Increasing stop positions, 0 to 1.
    colours : (s, 3) float64
        RGB of each stop in [0, 1].
    """

    positions: np.ndarray
    colours: np.ndarray

    @classmethod
    def from_hex(cls, hexes, *, reverse: bool = False) -> "ColourScale":
        """Evenly spaced stops from ``#rrggbb`` strings."""
        hexes = list(hexes)[::-1] if reverse else list(hexes)
        rgb = np.array([[int(h[i : i + 2], 16) for i in (1, 3, 5)] for h in hexes], dtype=np.float64) / 255.0
        return cls(np.linspace(0.0, 1.0, len(hexes)), rgb)

    @classmethod
    def from_bytes(cls, data: bytes, *, reverse: bool = False) -> "ColourScale":
        """Evenly spaced stops from RGB bytes (a 256-entry map)."""
        rgb = np.frombuffer(data, np.uint8).reshape(-1, 3).astype(np.float64) / 255.0
        rgb = rgb[::-1] if reverse else rgb
        return cls(np.linspace(0.0, 1.0, len(rgb)), rgb)

    def rgb(self, values, low: float, high: float) -> np.ndarray:
        """(n, 3) float64 colours of ``values`` between ``low`` and ``high``.

        ``low`` maps to the first stop, ``high`` to the last; values beyond
        them to the nearest end; with ``high <= low`` every value gets the
        first stop. NaN values are drawn at the first stop too: callers that
        mean "no value" colour those themselves.
        """
        values = np.asarray(values, dtype=np.float64)
        span = high - low
        if span > 0:
            t = np.clip((values - low) / span, 0.0, 1.0)
            t = np.where(np.isnan(t), 0.0, t)
        else:
            t = np.zeros(len(values))
        return np.stack([np.interp(t, self.positions, self.colours[:, c]) for c in range(3)], axis=1)


#: The pressure scale of every pressure picture: light at 0 Pa, dark at the top.
PRESSURE_SCALE = ColourScale.from_hex(PLOTLY_MAGMA, reverse=True)

_NAMED = {
    "pressure": lambda: PRESSURE_SCALE,
    "magma_r": lambda: ColourScale.from_bytes(MAGMA_R_BYTES),
    "magma": lambda: ColourScale.from_bytes(MAGMA_R_BYTES, reverse=True),
    "viridis": lambda: ColourScale.from_bytes(VIRIDIS_BYTES),
    "viridis_r": lambda: ColourScale.from_bytes(VIRIDIS_BYTES, reverse=True),
}


def colour_scale(scale) -> ColourScale:
    """A :class:`ColourScale` from a name, a ColourScale or a sequence of RGB colours.

    Parameters
    ----------
    scale : str, ColourScale or (s, 3) array_like
        A name (``pressure``, ``magma``, ``magma_r``, ``viridis``,
        ``viridis_r``), a scale, or colours in [0, 1] spaced evenly.

    Raises
    ------
    ValueError
        An unknown name or colours that are not (s >= 2, 3) in [0, 1].
    """
    if isinstance(scale, ColourScale):
        return scale
    if isinstance(scale, str):
        try:
            return _NAMED[scale]()
        except KeyError:
            msg = f"unknown colour map {scale!r}; expected one of {', '.join(_NAMED)} or a list of RGB colours"
            raise ValueError(msg) from None
    rgb = np.asarray(scale, dtype=np.float64)
    if rgb.ndim != 2 or rgb.shape[1] != 3 or len(rgb) < 2 or not np.all((rgb >= 0) & (rgb <= 1)):
        msg = f"a colour map given as colours must be (s >= 2, 3) RGB in [0, 1], got shape {rgb.shape}"
        raise ValueError(msg)
    return ColourScale(np.linspace(0.0, 1.0, len(rgb)), rgb)


def nice_ticks(low: float, high: float, count: int = 5) -> np.ndarray:
    """Round tick values in [low, high]: multiples of 1, 2 or 5 times a power of ten.

    About ``count`` ticks; ``[low]`` alone when the range is empty.
    """
    span = high - low
    if not span > 0:
        return np.array([float(low)])
    raw = span / count
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(s * power for s in (1, 2, 5, 10) if s * power >= raw)
    start = math.ceil(low / step - 1e-9) * step
    return np.arange(start, high + 1e-9 * span, step)
