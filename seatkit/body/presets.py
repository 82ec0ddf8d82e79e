"""Percentile manikins: ``p5-female`` ... ``p95-male`` from the ANSUR II survey.

``seatkit/data/bodies/presets.yaml`` (written by ``tools/fit_presets.py``)
holds, per preset, the survey's 5th, 50th or 95th percentile figures (ANSUR
II public data, Gordon et al. 2014) and the parametric model's inputs fitted
so that the body's *measured* sitting height, hip breadth (sitting) and
buttock-knee length (:mod:`seatkit.body.measure`) equal the survey's; stature
and mass are the survey's directly. See ``docs/bodies.md``.
"""

from __future__ import annotations

import functools
from typing import Any, Mapping

import yaml

from seatkit.resources import data_path

__all__ = ["PRESETS", "preset_table", "make_preset"]

#: Names of the percentile manikins.
PRESETS: tuple[str, ...] = ("p5-female", "p50-female", "p95-female", "p5-male", "p50-male", "p95-male")


@functools.lru_cache(maxsize=1)
def preset_table() -> dict:
    """The parsed ``presets.yaml``: ``source``, ``files_sha256`` and ``presets``."""
    return yaml.safe_load(data_path("bodies", "presets.yaml").read_text(encoding="utf-8"))


def make_preset(name: str, *, mass: float | None = None, height: float | None = None):
    """The rigged body of preset ``name``; ``mass`` or ``height`` override the survey's (the proportions stay)."""
    from seatkit.body.parametric import make_parametric_body

    p = preset_table()["presets"][name]
    survey, inputs = p["survey"], dict(p["model_inputs"])
    stature = float(height) if height is not None else survey["stature"]
    if height is not None:  # keep the preset's proportions at another height
        inputs = {k: v * stature / survey["stature"] for k, v in inputs.items()}
    return make_parametric_body(
        p["sex"],
        stature=stature,
        mass=float(mass) if mass is not None else survey["mass"],
        name=name,
        meta={"preset": name, "survey": survey},
        **inputs,
    )
