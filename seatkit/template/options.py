"""Declared options of template steps: one schema per step, checked at load.

A template step (:class:`seatkit.interfaces.TemplateStep`) declares every
option it accepts as an :class:`Option` in its ``options`` mapping: the
type, the unit, the default, the allowed range or choices and one line of
meaning. The same declaration

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

Types (``Option.type``):

``number``
    a real number (``int`` accepted), with ``unit`` (``m``, ``deg``, ``1``).
``count``
    a whole number.
``bool``
    ``true`` or ``false``.
``choice``
    one of ``choices`` (strings).
``rows`` / ``columns``
    a list of row or column names of the template.
``segments``
    a list of body segment names (:data:`seatkit.skeleton.SEGMENTS`).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

from seatkit.skeleton import SEGMENTS
from seatkit.yamlio import quote

__all__ = ["Option", "OPTION_TYPES", "check_step_options", "did_you_mean", "options_table"]

OPTION_TYPES = ("number", "count", "bool", "choice", "rows", "columns", "segments")


@dataclass(frozen=True)
class Option:
    """One option of a template step.

    Attributes
    ----------
    type : str
        One of :data:`OPTION_TYPES`.
    description : str
        One line: what it changes.
    default : object
        Value when the template does not give one; ``None``: the step
        decides (documented in ``description``, e.g. "all rows").
    unit : str
        ``m``, ``deg``, ``1`` (a ratio) or ``""`` (no unit).
    minimum, maximum : float, optional
        Inclusive range of a ``number`` or ``count``.
    choices : tuple of str
        The values of a ``choice``.
    required : bool
        The step cannot run without it (a template that leaves it out is
        refused at load).
    """

    type: str
    description: str
    default: Any = None
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple = ()
    required: bool = False

    def __post_init__(self):
        if self.type not in OPTION_TYPES:
            raise ValueError(f"Option type {self.type!r}: expected one of {', '.join(OPTION_TYPES)}")
        if self.type == "choice" and not self.choices:
            raise ValueError("a 'choice' Option needs choices")

    def expected(self) -> str:
        """What a value must be, in words (for messages and the docs)."""
        if self.type in ("number", "count"):
            what = "a number" if self.type == "number" else "a whole number"
            unit = f" ({self.unit})" if self.unit and self.unit != "1" else ""
            lo, hi = self.minimum, self.maximum
            if lo is not None and hi is not None:
                return f"{what} from {lo:g} to {hi:g}{unit}"
            if lo is not None:
                return f"{what} >= {lo:g}{unit}"
            if hi is not None:
                return f"{what} <= {hi:g}{unit}"
            return what + unit
        if self.type == "bool":
            return "true or false"
        if self.type == "choice":
            return "one of " + ", ".join(self.choices)
        return f"a list of {self.type[:-1]} names"


def did_you_mean(word: str, candidates: Sequence[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest candidate, or ``""``."""
    close = difflib.get_close_matches(str(word), [str(c) for c in candidates], n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def _check_value(opt: Option, value: Any, names: Mapping[str, Sequence[str]]) -> tuple[Any, str | None, int | None]:
    """(value as the step gets it, problem or None, index of a bad list item)."""
    t = opt.type
    if t in ("number", "count"):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
            return value, f"expected {opt.expected()}, got {quote(value)}", None
        if t == "count" and float(value) != int(value):
            return value, f"expected {opt.expected()}, got {quote(value)}", None
        if (opt.minimum is not None and value < opt.minimum) or (opt.maximum is not None and value > opt.maximum):
            return value, f"expected {opt.expected()}, got {quote(value)}", None
        return (int(value) if t == "count" else float(value)), None, None
    if t == "bool":
        if not isinstance(value, bool):
            return value, f"expected true or false, got {quote(value)}", None
        return value, None, None
    if t == "choice":
        if value not in opt.choices:
            return value, f"expected one of {', '.join(opt.choices)}, got {quote(value)}{did_you_mean(value, opt.choices)}", None
        return value, None, None
    allowed = list(names[t])
    if not isinstance(value, list) or not value:
        return value, f"expected {opt.expected()} (a non-empty list), got {quote(value)}", None
    for j, v in enumerate(value):
        if v not in allowed:
            hint = did_you_mean(v, allowed) if isinstance(v, str) else ""
            return value, f"unknown {t[:-1]} {quote(v)}; expected one of {', '.join(allowed)}{hint}", j
    return list(value), None, None


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
        Every given option (converted: counts to int, numbers to float) and
        the default of every other option whose default is not None.
    """
    names = {"rows": rows, "columns": columns, "segments": SEGMENTS}
    out = {}
    for key, value in given.items():
        if key in ignore:
            continue
        if key not in declared:
            have = ", ".join(sorted(declared)) or "none"
            raise fail((key,), f"step {step_name!r} has no option {key!r}; its options are: {have}{did_you_mean(key, list(declared))}")
        value, problem, index = _check_value(declared[key], value, names)
        if problem:
            raise fail((key,) if index is None else (key, index), problem)
        out[key] = value
    for key, opt in declared.items():
        if key not in out and opt.required:
            raise fail((), f"step {step_name!r} needs option {key!r} ({opt.expected()}: {opt.description})")
        if key not in out and opt.default is not None:
            out[key] = opt.default
    return out


def options_table(step) -> str:
    """The Markdown table of a step's options, after a line with its stage and prerequisites (as in ``docs/templates.md``)."""
    options: Mapping[str, Option] = step.options or {}
    requires = ", ".join(f"`{r}`" for r in step.requires) or "no other step"
    head = f"Stage `{step.stage}`; needs {requires} before it."
    if not options:
        return head + " No options."
    lines = [head, "", "| option | type | unit | default | allowed | meaning |", "|---|---|---|---|---|---|"]
    for key, opt in options.items():
        default = "required" if opt.required else "—" if opt.default is None else _fmt(opt.default)
        allowed = opt.expected()
        lines.append(f"| `{key}` | {opt.type} | {opt.unit or '—'} | {default} | {allowed} | {opt.description} |")
    return "\n".join(lines)


def _fmt(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(map(str, value)) + "]"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)
