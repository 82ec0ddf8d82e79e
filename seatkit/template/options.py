"""Declared options of template steps: one schema per step, checked at load.

A template step (:class:`seatkit.interfaces.TemplateStep`) declares every
option it accepts as a :class:`seatkit.options.Option` in its ``options``
mapping, the schema every component uses (:mod:`seatkit.options`). Here it

* checks a template's ``steps:`` entries when the template joins a registry
  (:func:`check_step_options`): an unknown key, a value of the wrong type or
  out of range, a row or column the template does not have, is one
  ``file:line: steps[i].key: what was expected`` error with a "did you mean"
  for a misspelt name;
* checks a recipe's ``template_params.steps`` overrides the same way;
* fills in the defaults, so that a step's ``run`` gets every option that has
  a default;
* generates the option tables of ``docs/templates.md``
  (:func:`options_table`; ``python -m seatkit.template.steps docs/templates.md``
  rewrites them, and a test keeps the docs equal to it).

A step's ``rows`` and ``columns`` options take the template's row and
column names; ``segments`` the body segment names.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

from seatkit.options import OPTION_TYPES, Option, check_options, did_you_mean
from seatkit.options import options_table as _table

__all__ = ["Option", "OPTION_TYPES", "check_step_options", "did_you_mean", "options_table"]


def check_step_options(
    step_name: str,
    declared: Mapping[str, Option],
    given: Mapping[str, Any],
    *,
    rows: Sequence[str],
    columns: Sequence[str],
    fail: Callable[[tuple, str], Exception],
    ignore: Sequence[str] = (),
) -> dict:
    """Check a step's options against its declaration; return them with the defaults.

    Parameters
    ----------
    step_name : str
        For messages.
    declared : mapping of str to Option
        The step's ``options``.
    given : mapping
        Options as written (the template's step entry, or a recipe override).
    rows, columns : sequence of str
        The template's row and column names (for ``rows``/``columns`` options).
    fail : callable
        ``fail(key_path, message)`` returns the exception to raise; the key
        path is relative to the step entry (``("width",)``, ``("rows", 2)``).
    ignore : sequence of str
        Keys of the entry that are not options (``step``, ``label``).

    Returns
    -------
    dict
        As :func:`seatkit.options.check_options`.
    """
    return check_options(f"step {step_name!r}", declared, given, fail=fail, names={"rows": rows, "columns": columns}, ignore=ignore)


def options_table(step) -> str:
    """The Markdown table of a step's options, after a line with its stage and prerequisites (as in ``docs/templates.md``)."""
    options: Mapping[str, Option] = step.options or {}
    requires = ", ".join(f"`{r}`" for r in step.requires) or "no other step"
    head = f"Stage `{step.stage}`; needs {requires} before it."
    if not options:
        return head + " No options."
    return head + "\n\n" + _table(options)
