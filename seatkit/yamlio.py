"""YAML documents that remember where each value came from.

Every YAML file seatkit reads (recipes, templates, poses, name maps) goes
through :func:`load_yaml`, which keeps the line of every key, and
:func:`validate`, which checks the data against a JSON schema and turns the
first problems into one :class:`~seatkit.errors.RecipeError` whose lines read
``recipe.yaml:7: bodies[0].pose: expected a string, got 3``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import yaml

from seatkit.errors import RecipeError

KeyPath = tuple  # of str and int

#: libyaml's parser when PyYAML was built with it (several times faster; the
#: templates are parsed at every start-up), else the pure-Python one: the same
#: nodes, marks and constructors either way. A syntax error is reported with
#: the pure-Python parser's message.
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def format_path(path: Iterable) -> str:
    """``("faces", 4, "segment")`` -> ``faces[4].segment``."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


@dataclass
class Document:
    """Parsed YAML data with the line (1-based) of every key path."""

    data: Any
    source: str
    lines: dict = field(default_factory=dict)

    def line(self, path: Iterable) -> int | None:
        """Line of ``path``, or of its nearest ancestor that has one."""
        path = tuple(path)
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return self.lines.get((), None)

    def where(self, path: Iterable) -> str:
        """``file:line: key.path`` for messages."""
        path = tuple(path)
        line = self.line(path)
        loc = f"{self.source}:{line}" if line else self.source
        return f"{loc}: {format_path(path)}"

    def error(self, path: Iterable, message: str) -> RecipeError:
        """A RecipeError located at ``path``."""
        return RecipeError(f"{self.where(path)}: {message}")


def _construct(node, path, lines, loader):
    lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out = {}
        for key_node, value_node in node.value:
            key = loader.construct_object(key_node, deep=True)
            if not isinstance(key, (str, int, float, bool)) or key is None:
                msg = f"line {key_node.start_mark.line + 1}: mapping keys must be plain names, got {key!r}"
                raise RecipeError(msg)
            key = str(key)
            if key in out:
                msg = f"line {key_node.start_mark.line + 1}: key {format_path(path + (key,))!r} is given twice"
                raise RecipeError(msg)
            out[key] = _construct(value_node, path + (key,), lines, loader)
            lines[path + (key,)] = key_node.start_mark.line + 1
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_construct(child, path + (i,), lines, loader) for i, child in enumerate(node.value)]
    return loader.construct_object(node, deep=True)


def parse_yaml(text: str, *, source: str = "<string>") -> Document:
    """Parse YAML text into a :class:`Document`.

    Raises
    ------
    RecipeError
        On a syntax error, with the file and line.
    """
    try:
        return _parse(text, source, _Loader)
    except yaml.MarkedYAMLError:
        if _Loader is yaml.SafeLoader:
            raise
    # a syntax error: parse again with the pure-Python parser, whose messages
    # say more ("found character '\t' that cannot start any token")
    return _parse(text, source, yaml.SafeLoader)


def _parse(text: str, source: str, loader_class) -> Document:
    loader = loader_class(text)
    try:
        node = loader.get_single_node()
        lines: dict = {}
        data = {} if node is None else _construct(node, (), lines, loader)
    except yaml.MarkedYAMLError as e:
        if loader_class is not yaml.SafeLoader:
            raise
        mark = e.problem_mark or e.context_mark
        line = f":{mark.line + 1}" if mark is not None else ""
        msg = f"{source}{line}: not valid YAML: {e.problem or e}"
        raise RecipeError(msg) from None
    except RecipeError as e:
        raise RecipeError(f"{source}: {e}") from None
    finally:
        loader.dispose()
    return Document(data, source, lines)


def load_yaml(path) -> Document:
    """Read and parse a YAML file (see :func:`parse_yaml`)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RecipeError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise RecipeError(f"{path}: cannot read: {e}") from None
    return parse_yaml(text, source=str(path))


_TYPE_NAMES = {
    "string": "a string",
    "number": "a number",
    "integer": "a whole number",
    "boolean": "true or false",
    "array": "a list",
    "object": "a mapping",
    "null": "nothing",
}


def _describe(error) -> str:
    """A plain-English message for one jsonschema error."""
    v = error.validator
    inst = error.instance
    if v == "type":
        want = error.validator_value
        want = [want] if isinstance(want, str) else want
        return f"expected {' or '.join(_TYPE_NAMES.get(w, w) for w in want)}, got {inst!r}"
    if v == "enum":
        return f"expected one of {', '.join(map(str, error.validator_value))}; got {inst!r}"
    if v == "required":
        missing = [k for k in error.validator_value if k not in inst]
        return f"missing required key {missing[0]!r}" if missing else error.message
    if v == "additionalProperties":
        allowed = sorted(error.schema.get("properties", {}))
        extra = sorted(set(inst) - set(allowed))
        return f"unknown key {extra[0]!r}; expected one of {', '.join(allowed)}" if extra else error.message
    if v in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum"):
        op = {"minimum": ">=", "exclusiveMinimum": ">", "maximum": "<=", "exclusiveMaximum": "<"}[v]
        return f"expected a value {op} {error.validator_value}, got {inst!r}"
    if v in ("minItems", "maxItems"):
        word = "at least" if v == "minItems" else "at most"
        return f"expected {word} {error.validator_value} items, got {len(inst)}"
    if v == "pattern":
        return f"{inst!r} does not match the expected form {error.validator_value!r}"
    return error.message


def validate(doc: Document, schema: dict, *, max_errors: int = 5) -> None:
    """Check ``doc.data`` against a JSON schema.

    Raises
    ------
    RecipeError
        Listing up to ``max_errors`` problems, one per line, each as
        ``file:line: key.path: what was expected``.
    """
    import jsonschema

    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(doc.data), key=lambda e: (doc.line(e.absolute_path) or 0, list(map(str, e.absolute_path))))
    if not errors:
        return
    lines = []
    for e in errors[:max_errors]:
        path = tuple(e.absolute_path)
        # oneOf/anyOf: report the most specific sub-error
        if e.context:
            best = jsonschema.exceptions.best_match(e.context)
            path = tuple(best.absolute_path)
            e = best
        if e.validator == "additionalProperties" and isinstance(e.instance, dict):
            extra = sorted(set(e.instance) - set(e.schema.get("properties", {})))
            if extra:
                path = path + (extra[0],)
        lines.append(f"{doc.where(path)}: {_describe(e)}")
    if len(errors) > max_errors:
        lines.append(f"... and {len(errors) - max_errors} more problems")
    raise RecipeError("\n".join(lines))
