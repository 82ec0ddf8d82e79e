"""A rigged body by name or path: the parametric defaults, seatkit ``.npz`` rigs, glTF/GLB.

:func:`load_rig` is the dispatcher above the three readers
(:mod:`seatkit.body.parametric`, :mod:`seatkit.body.rig`,
:mod:`seatkit.body.gltf`); it lives apart from them so that each reader
imports the rig maths (:func:`seatkit.body.rig.make_rig`) without importing
the others.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from seatkit.body.rig import DEFAULT_BODIES, load_rig_file
from seatkit.constants import DEFAULT_BODY_MASS
from seatkit.errors import InputError, RecipeError
from seatkit.model import RiggedBody

__all__ = ["load_rig"]


def _load_gltf_rig(path: Path, *, mass: float, params: Mapping[str, Any] | None) -> RiggedBody:
    """A skinned glTF/GLB body, through :func:`seatkit.body.gltf.load_gltf_rig`."""
    try:
        from seatkit.body.gltf import load_gltf_rig
    except ImportError as e:
        msg = f"{path}: glTF body import is not available in this installation ({e})"
        raise InputError(msg) from None
    return load_gltf_rig(path, mass=mass, **dict(params or {}))


def load_rig(body: str | Path = "default-male", *, mass: float | None = None, params: Mapping[str, Any] | None = None) -> RiggedBody:
    """Load a rigged body by name or path.

    Parameters
    ----------
    body : str or Path
        ``default-male``, ``default-female`` (made by the parametric model at
        ``mass``, with ``params`` such as ``height``), or a path to a seatkit
        ``.npz``/``.glb``/``.gltf`` rig (body models of plugins, e.g. ``anny``,
        are reached through a registry instead:
        ``registry.get("body_model", name).make_body``).
    mass : float, optional
        Total body mass, kg. Default: the model's (75 kg for ``default-male``
        and rig files, 55 kg for ``default-female``, a preset's own).
    params : mapping, optional
        Extra parameters of a glTF rig (``name_map``).

    Returns
    -------
    RiggedBody

    Raises
    ------
    InputError
        A rig file that cannot be read or is invalid.
    RecipeError
        An unknown body name.
    """
    spec = str(body)
    given = {} if mass is None else {"mass": float(mass)}
    mass = DEFAULT_BODY_MASS if mass is None else mass
    if spec in DEFAULT_BODIES:  # the parametric model at this mass (the shipped mesh is its anchor)
        from seatkit.body.parametric import make_default_body

        return make_default_body(spec, {**given, **dict(params or {})})
    path = Path(spec)
    suffix = path.suffix.lower()
    if suffix in (".glb", ".gltf"):
        return _load_gltf_rig(path, mass=mass, params=params)
    if suffix == ".npz" or path.exists():
        return load_rig_file(path, mass=mass)
    msg = (
        f"unknown body {spec!r}: expected a path to a .npz/.glb/.gltf rig or one of {', '.join(sorted(DEFAULT_BODIES))} "
        "(other body models are found through a plugin manager's registry: registry.get('body_model', name))"
    )
    raise RecipeError(msg)
