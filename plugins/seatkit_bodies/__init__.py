"""Built-in body models and the shipped pose library.

Registers the body models ``default-male``, ``default-female`` (the embedded
MakeHuman-derived bodies, made to a size by the parametric model), the
percentile manikins ``p5-female`` ... ``p95-male`` and ``file`` (a seatkit ``.npz`` rig, parameter
``path``), and the pose folder ``seatkit/data/poses``. It uses the same hooks
a third-party plugin would.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from seatkit import hookimpl


def _params(name: str, params: Mapping[str, Any], allowed: tuple[str, ...]) -> dict:
    from seatkit.constants import DEFAULT_BODY_MASS
    from seatkit.errors import RecipeError

    params = dict(params or {})
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        msg = f"body model {name!r}: unknown parameter(s) {', '.join(unknown)}; expected {', '.join(allowed)}"
        raise RecipeError(msg)
    params.setdefault("mass", DEFAULT_BODY_MASS)
    return params


class DefaultBody:
    """An embedded default body (MakeHuman data, CC0) made to a size by the parametric model, numpy only.

    Parameters: ``mass`` (kg, default 75), ``height`` (stature in m, default
    the body's own 1.75 / 1.62), ``sitting_height``, ``buttock_knee``,
    ``hip_breadth`` (m, default the model's own proportions).
    """

    def __init__(self, name: str, description: str):
        self.name = name
        self.description = description

    @property
    def params_schema(self) -> dict:
        """The parameters (JSON schema), each with this body's own value as its default (None: its own proportions)."""
        from seatkit.body.parametric import DEFAULT_SIZES

        _, stature, mass = DEFAULT_SIZES[self.name]
        return _size_schema(mass, stature, proportions=True)

    def make_body(self, *, params: Mapping[str, Any]):
        from seatkit.body.parametric import make_default_body

        return make_default_body(self.name, params)

    def pose(self, rig, pose, *, ground: bool = True):
        from seatkit.body.skinning import pose_rig

        return pose_rig(rig, pose, ground=ground)


class PresetBody(DefaultBody):
    """A percentile manikin (ANSUR II); ``mass`` and ``height`` may override the survey's."""

    def __init__(self, name: str, description: str):
        self.name = name
        self.description = description

    @property
    def params_schema(self) -> dict:
        """``mass`` and ``height``, each with the survey's value as its default."""
        from seatkit.body.presets import preset_table

        survey = preset_table()["presets"][self.name]["survey"]
        return _size_schema(survey["mass"], survey["stature"], proportions=False)

    def make_body(self, *, params: Mapping[str, Any]):
        from seatkit.body.presets import make_preset
        from seatkit.errors import RecipeError

        params = dict(params or {})
        unknown = sorted(set(params) - {"mass", "height"})
        if unknown:
            msg = f"body model {self.name!r}: unknown parameter(s) {', '.join(unknown)}; expected mass, height"
            raise RecipeError(msg)
        p = {k: _number(self.name, k, v) for k, v in params.items()}
        return make_preset(self.name, mass=p.get("mass"), height=p.get("height"))


def _size_schema(mass: float, stature: float, *, proportions: bool) -> dict:
    """The JSON schema of a parametric body's parameters; defaults are the body's own values."""
    from seatkit.body.parametric import BMI_RANGE, STATURE_RANGE

    props = {
        "mass": {"type": "number", "title": "mass", "unit": "kg", "default": mass, "minimum": 20, "maximum": 300,
                 "description": f"body mass (a BMI of {BMI_RANGE[0]:g}-{BMI_RANGE[1]:g} at the height)"},
        "height": {"type": "number", "title": "height", "unit": "m", "default": stature, "minimum": STATURE_RANGE[0],
                   "maximum": STATURE_RANGE[1], "description": "standing height (stature)"},
    }
    if proportions:
        for key, title in (("sitting_height", "sitting height"), ("buttock_knee", "buttock-knee length"), ("hip_breadth", "hip breadth")):
            props[key] = {"type": "number", "title": title, "unit": "m", "default": None, "minimum": 0.1, "maximum": 1.5,
                          "description": f"{title}; default: the body's own proportions at its height"}
    return {"type": "object", "additionalProperties": False, "properties": props}


def _number(model: str, key: str, value) -> float:
    from seatkit.errors import RecipeError

    if isinstance(value, bool) or not isinstance(value, (int, float)):
        msg = f"body model {model!r}: parameter {key} must be a number, got {value!r}"
        raise RecipeError(msg)
    return float(value)


class FileBody:
    """A rigged body read from a seatkit ``.npz`` rig file (parameter ``path``)."""

    name = "file"
    description = "A rigged body from a file: a seatkit .npz rig or a skinned .glb/.gltf (params: path, mass, name_map)"

    def make_body(self, *, params: Mapping[str, Any]):
        from seatkit.body.loading import load_rig
        from seatkit.errors import RecipeError

        p = _params(self.name, params, ("mass", "path", "name_map"))
        if "path" not in p:
            msg = "body model 'file': parameter 'path' (a .npz rig or .glb/.gltf body) is required"
            raise RecipeError(msg)
        extra = {"name_map": p["name_map"]} if "name_map" in p else None
        return load_rig(Path(p["path"]), mass=p["mass"], params=extra)

    def pose(self, rig, pose, *, ground: bool = True):
        from seatkit.body.skinning import pose_rig

        return pose_rig(rig, pose, ground=ground)


@hookimpl
def seatkit_register_body_models():
    return [
        DefaultBody("default-male", "Adult male, 1.75 m by default, MakeHuman-derived (CC0); keys height, mass, sitting_height, buttock_knee, hip_breadth"),
        DefaultBody("default-female", "Adult female, 1.62 m by default, MakeHuman-derived (CC0); keys height, mass, sitting_height, buttock_knee, hip_breadth"),
        *_presets(),
        FileBody(),
    ]


def _presets():
    from seatkit.body.presets import PRESETS, preset_table

    table = preset_table()["presets"]
    out = []
    for name in PRESETS:
        s = table[name]["survey"]
        out.append(PresetBody(name, f"ANSUR II {name.split('-')[0][1:]}th percentile {table[name]['sex']}: {s['stature']:.3f} m, {s['mass']:.1f} kg"))
    return out


@hookimpl
def seatkit_register_pose_dirs():
    from seatkit.body.poses import builtin_pose_dir

    return [builtin_pose_dir()]
