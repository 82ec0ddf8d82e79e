"""Percentile manikins: ``p5-female`` ... ``p95-male`` from the ANSUR II survey.

``seatkit/data/bodies/presets.yaml`` (written by ``tools/fit_presets.py``)
holds, per preset, the survey's 5th, 50th or 95th percentile figures (ANSUR
II public data, Gordon et al. 2014; unweighted percentiles of the public
release) and the parametric model's inputs fitted so that the body's
*measured* sitting height, hip breadth (sitting), buttock-knee length,
popliteal height, knee height sitting and buttock-popliteal length
(:mod:`seatkit.body.measure`) equal the survey's; stature and mass are the
survey's directly. See ``docs/bodies.md``.
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
    # the packaged file: libyaml's safe loader where PyYAML has it (10x faster; the same data)
    return yaml.load(data_path("bodies", "presets.yaml").read_text(encoding="utf-8"), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


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


#: Rows of the survey table: (measurement of seatkit.body.measure, survey key, label).
TABLE_ROWS = (
    ("stature", "stature", "stature"),
    ("mass", "mass", "mass (kg)"),
    ("sitting_height", "sitting_height", "sitting height"),
    ("hip_breadth_sitting", "hip_breadth", "hip breadth, sitting"),
    ("buttock_knee_length", "buttock_knee", "buttock-knee length"),
    ("popliteal_height", "popliteal_height", "popliteal height"),
    ("knee_height_sitting", "knee_height_sitting", "knee height, sitting"),
    ("buttock_popliteal_length", "buttock_popliteal_length", "buttock-popliteal length"),
    ("thigh_clearance", "thigh_clearance", "thigh clearance (not fitted)"),
    ("elbow_rest_height", "elbow_rest_height", "elbow rest height (not fitted)"),
    ("waist_circumference", "waist_circumference", "waist circumference (not fitted)"),
    ("hip_circumference", "buttock_circumference", "hip / buttock circumference (not fitted)"),
)


def survey_table() -> str:
    """The requested (survey) vs built (measured) figures of every preset, as a Markdown table."""
    from seatkit.body.measure import measure_rig
    from seatkit.body.anthropometry import body_density

    table = preset_table()["presets"]
    lines = ["| preset | measurement | survey | built | difference |", "|---|---|---|---|---|"]
    for name in PRESETS:
        survey = table[name]["survey"]
        m = measure_rig(make_preset(name))
        for key, figure, label in TABLE_ROWS:
            want, got = survey[figure], getattr(m, key)
            unit = "" if key == "mass" else " m"
            lines.append(f"| {name} | {label} | {want:.3f}{unit} | {got:.3f}{unit} | {100 * (got / want - 1):+.1f} % |")
        mass = m.volume * body_density(m.stature, m.mass)
        lines.append(f"| {name} | volume x density (kg) | {m.mass:.1f} | {mass:.1f} | {100 * (mass / m.mass - 1):+.1f} % |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(survey_table())
