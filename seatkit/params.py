"""The parameters a refiner (or the flat-patch template) runs with.

A refiner declares its options (:class:`seatkit.options.Option`, the schema
every component uses) as its ``options`` attribute; a recipe gives
overrides under ``refiners[i].params``. :func:`seatkit.recipe.check_recipe`
checks them against the declaration before any geometry (with the recipe's
file and line); the refiner calls :func:`component_params` again when it
runs, so that a caller of the library that skips the recipe gets the same
one-line :class:`~seatkit.errors.RecipeError` and the same defaults.
"""

from __future__ import annotations

from typing import Any, Mapping

from seatkit.errors import RecipeError
from seatkit.messages import format_path
from seatkit.options import Option, check_options

__all__ = ["component_params", "refiner_params"]


def component_params(owner: str, declared: Mapping[str, Option], params: Mapping[str, Any] | None, *, where: tuple = ()) -> dict[str, Any]:
    """``params`` checked against ``declared``, with every default filled in.

    Parameters
    ----------
    owner : str
        Who takes them, for messages (``"refiner 'optimize'"``).
    declared : mapping of str to Option
    params : mapping or None
        Overrides.
    where : tuple
        Key path of ``params`` in the recipe, for messages
        (``("refiners", "optimize")``).

    Returns
    -------
    dict

    Raises
    ------
    RecipeError
        ``refiners.optimize.key: ...`` on an unknown key (with "did you
        mean") or a value of the wrong type or range.
    """

    def fail(path, message):
        return RecipeError(f"{format_path(where + tuple(path))}: {message}")

    return check_options(owner, declared, params, fail=fail)


def refiner_params(refiner: str, declared: Mapping[str, Option], params: Mapping[str, Any] | None) -> dict[str, Any]:
    """A refiner's parameters: its declared defaults overridden by ``params`` (see :func:`component_params`)."""
    return component_params(f"refiner {refiner!r}", declared, params, where=("refiners", refiner))
