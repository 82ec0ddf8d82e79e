"""Declared options: one schema for every component that takes settings.

Template steps, refiners, exporters, pressure solvers and the structural
analysis each declare the options they accept as a mapping of name to
:class:`Option` (``options`` on the component; :data:`seatkit.structure.build.OPTIONS`
for the ``structure`` section): the type, the unit, the default, the
allowed range or choices and one line of meaning. The same declaration

* checks what a user wrote (:func:`check_options`): an unknown key (with a
  "did you mean" for a misspelt one), a value of the wrong type, out of
  range or not among the choices, a missing required option. The caller
  says where the values came from (``fail``), so that every problem is one
  ``file:line: key.path: what was expected`` line, before any geometry;
* fills in the defaults (written once, in the declaration:
  :func:`defaults`), so that a component gets every option that has one;
* generates the documentation's option tables (:func:`options_table`).

Types (``Option.type``):

``number``
    a real number (``int`` accepted), with ``unit`` (``m``, ``deg``, ``1``).
``count``
    a whole number.
``bool``
    ``true`` or ``false``.
``choice``
    one of ``choices`` (strings).
``text``
    a string.
``rows`` / ``columns``
    a list of row or column names of the template (template steps only).
``segments``
    a list of body segment names (:data:`seatkit.skeleton.SEGMENTS`).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

from seatkit.messages import quote

__all__ = ["Option", "OPTION_TYPES", "check_options", "defaults", "did_you_mean", "json_schema", "options_table"]

OPTION_TYPES = ("number", "count", "bool", "choice", "text", "rows", "columns", "segments")

#: Longest list of option names quoted in a message, characters.
MAX_LISTED = 200

#: Types whose value is a list of names (checked against the names the caller gives).
NAME_LISTS = ("rows", "columns", "segments")


@dataclass(frozen=True)
class Option:
    """One declared option.

    Attributes
    ----------
    type : str
        One of :data:`OPTION_TYPES`.
    description : str
        One line: what it changes.
    default : object
        Value when nothing is given; ``None``: the component decides
        (documented in ``description``, e.g. "all rows").
    unit : str
        ``m``, ``deg``, ``1`` (a ratio) or ``""`` (no unit).
    minimum, maximum : float, optional
        Inclusive range of a ``number`` or ``count``.
    choices : tuple of str
        The values of a ``choice``.
    required : bool
        The component cannot run without it (leaving it out is refused).
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
        if self.type == "text":
            return "a string"
        return f"a list of {self.type[:-1]} names"


def did_you_mean(word: str, candidates: Sequence[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest candidate, or ``""``."""
    close = difflib.get_close_matches(str(word), [str(c) for c in candidates], n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def defaults(declared: Mapping[str, Option]) -> dict[str, Any]:
    """``{name: default}`` of every declared option whose default is not None."""
    return {key: opt.default for key, opt in declared.items() if opt.default is not None}


def json_schema(declared: Mapping[str, Option]) -> dict:
    """A JSON schema of a mapping of the declared options (for a YAML section checked with :func:`seatkit.yamlio.validate`)."""
    properties = {}
    for key, opt in declared.items():
        if opt.type in ("number", "count"):
            prop: dict = {"type": "number" if opt.type == "number" else "integer"}
            if opt.minimum is not None:
                prop["minimum"] = opt.minimum
            if opt.maximum is not None:
                prop["maximum"] = opt.maximum
        elif opt.type == "bool":
            prop = {"type": "boolean"}
        elif opt.type == "choice":
            prop = {"enum": list(opt.choices)}
        elif opt.type == "text":
            prop = {"type": "string"}
        else:
            prop = {"type": "array", "minItems": 1, "items": {"type": "string"}}
        properties[key] = prop
    required = [key for key, opt in declared.items() if opt.required]
    return {"type": "object", "additionalProperties": False, "properties": properties, **({"required": required} if required else {})}


def _check_value(opt: Option, value: Any, names: Mapping[str, Sequence[str]]) -> tuple[Any, str | None, int | None]:
    """(value as the component gets it, problem or None, index of a bad list item)."""
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
            hint = did_you_mean(value, opt.choices) if isinstance(value, str) else ""
            return value, f"expected one of {', '.join(opt.choices)}, got {quote(value)}{hint}", None
        return value, None, None
    if t == "text":
        if not isinstance(value, str):
            return value, f"expected a string, got {quote(value)}", None
        return value, None, None
    allowed = list(names.get(t, ()))
    if not isinstance(value, list) or not value:
        return value, f"expected {opt.expected()} (a non-empty list), got {quote(value)}", None
    for j, v in enumerate(value):
        if v not in allowed:
            hint = did_you_mean(v, allowed) if isinstance(v, str) else ""
            return value, f"unknown {t[:-1]} {quote(v)}; expected one of {', '.join(allowed)}{hint}", j
    return list(value), None, None


def check_options(
    owner: str,
    declared: Mapping[str, Option],
    given: Mapping[str, Any] | None,
    *,
    fail: Callable[[tuple, str], Exception],
    names: Mapping[str, Sequence[str]] | None = None,
    ignore: Sequence[str] = (),
) -> dict:
    """Check options against their declaration; return them with the defaults.

    Parameters
    ----------
    owner : str
        Who takes them, for messages (``"step 'border'"``, ``"refiner 'optimize'"``).
    declared : mapping of str to Option
    given : mapping or None
        Options as written (a template's step entry, a recipe's ``params``).
    fail : callable
        ``fail(key_path, message)`` returns the exception to raise; the key
        path is relative to ``given`` (``("width",)``, ``("rows", 2)``).
    names : mapping, optional
        The allowed names of ``rows``, ``columns`` and ``segments`` options
        (``segments`` defaults to :data:`seatkit.skeleton.SEGMENTS`).
    ignore : sequence of str
        Keys of ``given`` that are not options (a step entry's ``step``).

    Returns
    -------
    dict
        Every given option (converted: counts to int, numbers to float) and
        the default of every other option whose default is not None.
    """
    if given is not None and not isinstance(given, Mapping):
        raise fail((), f"expected a mapping of option names to values, got {quote(given)}")
    if names is None or "segments" not in names:
        from seatkit.skeleton import SEGMENTS

        names = {**(names or {}), "segments": SEGMENTS}
    out = {}
    for key, value in dict(given or {}).items():
        if key in ignore:
            continue
        if key not in declared:
            have = ", ".join(sorted(declared)) or "none"
            if len(have) > MAX_LISTED:  # one line stays short: the first names, and how many more
                have = have[:MAX_LISTED].rsplit(", ", 1)[0] + f", ... ({len(declared)} in all)"
            raise fail((key,), f"{owner} has no option {quote(key)}; its options are: {have}{did_you_mean(key, list(declared))}")
        value, problem, index = _check_value(declared[key], value, names)
        if problem:
            raise fail((key,) if index is None else (key, index), problem)
        out[key] = value
    for key, opt in declared.items():
        if key not in out and opt.required:
            raise fail((), f"{owner} needs option {key!r} ({opt.expected()}: {opt.description})")
        if key not in out and opt.default is not None:
            out[key] = opt.default
    return out


def options_table(declared: Mapping[str, Option]) -> str:
    """The Markdown table of declared options (option, type, unit, default, allowed, meaning)."""
    lines = ["| option | type | unit | default | allowed | meaning |", "|---|---|---|---|---|---|"]
    for key, opt in declared.items():
        default = "required" if opt.required else "—" if opt.default is None else _fmt(opt.default)
        lines.append(f"| `{key}` | {opt.type} | {opt.unit or '—'} | {default} | {opt.expected()} | {opt.description} |")
    return "\n".join(lines)


def _fmt(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(map(str, value)) + "]"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)
