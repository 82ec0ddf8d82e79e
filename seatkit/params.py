"""Parameter handling shared by the refiners and the flat-patch template.

Each refiner declares its defaults as a dict; the cage's
``meta["refiners"]`` (which a template written in Python may set) and the
recipe override them by key. Unknown keys are user mistakes
and raise :class:`~seatkit.errors.RecipeError` naming the refiner, the key and
the keys that exist.
"""

from __future__ import annotations

from typing import Any, Mapping

from seatkit.errors import RecipeError

__all__ = ["merge_params", "refiner_params"]


def merge_params(
    refiner: str, defaults: Mapping[str, Any], params: Mapping[str, Any] | None
) -> dict[str, Any]:
    """Defaults overridden by ``params``, with types checked.

    Parameters
    ----------
    refiner : str
        Refiner name, for messages.
    defaults : mapping
        Every accepted key with its default value; the default's type is the
        expected type (ints accept ints, floats accept ints and floats, bools
        accept bools only).
    params : mapping or None
        Overrides.

    Returns
    -------
    dict

    Raises
    ------
    RecipeError
        On an unknown key or a value of the wrong type.
    """
    merged = dict(defaults)
    for key, value in dict(params or {}).items():
        if key not in defaults:
            msg = (
                f"refiners.{refiner}.{key}: unknown parameter; "
                f"expected one of {', '.join(sorted(defaults))}"
            )
            raise RecipeError(msg)
        want = defaults[key]
        if isinstance(want, bool):
            ok = isinstance(value, bool)
        elif isinstance(want, int):
            ok = isinstance(value, int) and not isinstance(value, bool)
        elif isinstance(want, float):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            value = float(value) if ok else value
        else:
            ok = isinstance(value, type(want))
        if not ok:
            msg = (
                f"refiners.{refiner}.{key}: expected {type(want).__name__}, "
                f"got {value!r} ({type(value).__name__})"
            )
            raise RecipeError(msg)
        merged[key] = value
    return merged


def refiner_params(
    refiner: str, defaults: Mapping[str, Any], mesh_meta: Mapping[str, Any], params: Mapping[str, Any] | None
) -> dict[str, Any]:
    """A refiner's parameters: its defaults, then the template's, then ``params``.

    A template written in Python (a plugin's) may give its own defaults in
    ``ControlMesh.meta["refiners"]``, a mapping of refiner name to
    parameters; YAML templates have no such section (their schema refuses a
    ``refiners:`` key), so their cages use the refiners' defaults. Recipe
    ``params`` win.

    Parameters
    ----------
    refiner : str
    defaults : mapping
    mesh_meta : mapping
        ``ControlMesh.meta``.
    params : mapping or None

    Returns
    -------
    dict
    """
    section = mesh_meta.get("refiners") or {}
    template_params = (section.get(refiner) or {}) if isinstance(section, Mapping) else {}
    merged = merge_params(refiner, defaults, template_params)
    return merge_params(refiner, merged, params)
