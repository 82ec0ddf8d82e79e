"""The boundary manikins of a population: a recipe's ``sitters: {population: ...}`` expanded to body entries.

Kept apart from :mod:`seatkit.sitters` (which designs for them) so that
reading a recipe needs nothing of the design: :mod:`seatkit.recipe`
expands the mapping as it checks the recipe.
"""

from __future__ import annotations

from typing import Any, Mapping

from seatkit.errors import RecipeError

__all__ = ["POPULATIONS", "SEXES", "expand_population"]

#: Populations whose boundary manikins are preset bodies: name -> (preset name pattern, percentiles, sexes).
POPULATIONS: dict[str, dict] = {
    "ansur-ii": {"pattern": "p{percentile}-{sex}", "percentiles": (5, 50, 95), "sexes": ("female", "male")},
}

#: How a recipe may name a sex: the short and the long form.
SEXES = {"f": "female", "female": "female", "m": "male", "male": "male"}


def expand_population(spec: Mapping[str, Any], default_pose: str = "upright-sitting") -> list[dict]:
    """The recipe body entries of a ``sitters: {population: ...}`` mapping, in sex then percentile order.

    Parameters
    ----------
    spec : mapping
        ``population`` (a key of :data:`POPULATIONS`), ``percentiles``
        (a subset of the population's), ``sexes`` (``f``/``m`` or
        ``female``/``male``), ``pose`` (default ``default_pose``) and
        ``frame``.

    Raises
    ------
    RecipeError
        ``sitters.KEY: ...`` naming what was expected.
    """
    name = spec.get("population")
    if name not in POPULATIONS:
        raise RecipeError(f"sitters.population: expected one of {', '.join(POPULATIONS)}, got {name!r}")
    pop = POPULATIONS[name]
    percentiles = list(spec.get("percentiles", pop["percentiles"]))
    for k, q in enumerate(percentiles):
        if isinstance(q, bool) or q not in pop["percentiles"]:
            raise RecipeError(f"sitters.percentiles[{k}]: {name} has the percentiles {', '.join(map(str, pop['percentiles']))}, got {q!r}")
    sexes = []
    for k, s in enumerate(spec.get("sexes", pop["sexes"])):
        if s not in SEXES:
            raise RecipeError(f"sitters.sexes[{k}]: expected one of f, m, female, male, got {s!r}")
        sexes.append(SEXES[s])
    if not percentiles or not sexes:
        raise RecipeError("sitters: a population needs at least one percentile and one sex")
    pose = spec.get("pose", default_pose)
    out = []
    for sex in dict.fromkeys(sexes):
        for q in dict.fromkeys(percentiles):
            out.append({"model": pop["pattern"].format(percentile=q, sex=sex), "params": {}, "pose": pose, "frame": int(spec.get("frame", 0))})
    return out
