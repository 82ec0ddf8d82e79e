"""A finished design read back: ``design.npz`` with its recipe checked, for ``seatkit evaluate`` and ``seatkit trial``."""

from __future__ import annotations

from pathlib import Path

__all__ = ["load_checked_design"]


def load_checked_design(path):
    """:func:`seatkit.state.load_design`, its recipe checked as ``seatkit evaluate`` and ``seatkit trial`` use it.

    The recipe must pass the recipe schema (it is returned normalised, every
    key present), and its ``surface_level`` must not refine the final cage
    past :data:`~seatkit.subdivision.catmull_clark.MAX_REFINED_FACES` quads.

    Raises
    ------
    InputError
        One line naming the file and the recipe's key.
    """
    from seatkit.errors import InputError, SeatkitError
    from seatkit.messages import one_line
    from seatkit.recipe import RECIPE_SCHEMA, load_recipe
    from seatkit.subdivision.catmull_clark import MAX_REFINED_FACES
    from seatkit.state import load_design
    from seatkit.yamlio import Document, validate

    path = Path(path)
    recipe, bodies, mesh, initial = load_design(path)  # lambda "inf" read as the number
    try:
        validate(Document(recipe, f"{path}: header.recipe"), RECIPE_SCHEMA)
        recipe, _ = load_recipe(recipe)  # normalised: every key evaluate reads is present
    except SeatkitError as e:
        raise InputError(one_line(f"{path}: header.recipe: {e}" if not str(e).startswith(str(path)) else str(e))) from None
    level = recipe.get("surface_level", 3)
    quads = 4 * len(mesh.faces) * 4 ** (level - 1)  # evaluate refines the final quad cage this far
    if quads > MAX_REFINED_FACES:
        raise InputError(f"{path}: header.recipe.surface_level: {level} refines the cage past {MAX_REFINED_FACES:,} quads")
    return recipe, bodies, mesh, initial
