"""Built-in body models and the shipped pose library.

Registers the body models ``default-male``, ``default-female`` (the embedded
MakeHuman-derived bodies) and ``file`` (a seatkit ``.npz`` rig, parameter
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
    """An embedded default body (MakeHuman data, CC0), numpy only."""

    def __init__(self, name: str, description: str):
        self.name = name
        self.description = description

    def make_body(self, *, params: Mapping[str, Any]):
        from seatkit.body.rig import default_body_path, load_rig_file

        p = _params(self.name, params, ("mass",))
        return load_rig_file(default_body_path(self.name), mass=p["mass"], name=self.name)

    def pose(self, rig, pose, *, ground: bool = True):
        from seatkit.body.skinning import pose_rig

        return pose_rig(rig, pose, ground=ground)


class FileBody:
    """A rigged body read from a seatkit ``.npz`` rig file (parameter ``path``)."""

    name = "file"
    description = "A rigged body from a file: a seatkit .npz rig or a skinned .glb/.gltf (params: path, mass, name_map)"

    def make_body(self, *, params: Mapping[str, Any]):
        from seatkit.body.rig import load_rig
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
        DefaultBody("default-male", "Adult male, 1.75 m, MakeHuman-derived (CC0), 13,348 vertices"),
        DefaultBody("default-female", "Adult female, 1.62 m, MakeHuman-derived (CC0), 13,348 vertices"),
        FileBody(),
    ]


@hookimpl
def seatkit_register_pose_dirs():
    from seatkit.body.poses import builtin_pose_dir

    return [builtin_pose_dir()]
