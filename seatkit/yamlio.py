"""YAML documents that remember where each value came from.

Every YAML file seatkit reads (recipes, templates, poses, name maps, batch
lists) goes through :func:`load_yaml` (or, for readers that walk the nodes
themselves, :func:`compose_yaml`), which keeps the line of every key, and
:func:`validate`, which checks the data against a JSON schema and turns the
first problem into one :class:`~seatkit.errors.RecipeError` line such as
``recipe.yaml:7: bodies[0].pose: expected a string, got 3``.

The loader is safe against hostile files (``seatkit serve`` takes uploads):
only YAML's plain types are built (``yaml.SafeLoader``'s constructors), text
must be UTF-8 (a bad byte is named by its offset), and before any node is
built an event pass refuses documents nested deeper than :data:`MAX_DEPTH`
or that would grow past :data:`MAX_NODES` nodes once every alias is expanded
(an "alias bomb" of a few hundred bytes otherwise takes minutes and
gigabytes), and aliases that refer to themselves. JSON-schema numbers are
finite (``.nan``, ``.inf`` and integers beyond 2**63 are refused) and an
"integer" is an integer, not ``1.0`` nor ``true`` (see :func:`strict_validator`),
and ``1e6`` is read as the number it is in YAML 1.2 and JSON.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import yaml

from seatkit.errors import RecipeError
from seatkit.io import MAX_FILE_BYTES, read_user_file
from seatkit.messages import clip, format_path, quote

KeyPath = tuple  # of str and int

#: libyaml's parser when PyYAML was built with it (several times faster; the
#: templates are parsed at every start-up), else the pure-Python one: the same
#: nodes, marks and constructors either way. A syntax error is reported with
#: the pure-Python parser's message.
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

#: YAML 1.2 (and JSON) floats that YAML 1.1 reads as strings: ``1e6``,
#: ``2E-3``, ``1.5e3`` (1.1 wants a dot and a signed exponent).
_FLOAT_12 = re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$")


class _SafeLoader(yaml.SafeLoader):
    """PyYAML's safe loader, reading ``1e6`` as a number."""


_SafeLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789"))


def _without_dates(loader_class) -> None:
    """Read ``2001-02-30`` as text: JSON has no dates, and YAML's date constructor crashes on some."""
    loader_class.yaml_implicit_resolvers = {
        first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:timestamp"]
        for first, resolvers in loader_class.yaml_implicit_resolvers.items()
    }


_without_dates(_SafeLoader)
if _Loader is not yaml.SafeLoader:

    class _CSafeLoader(_Loader):
        """libyaml's safe loader, reading ``1e6`` as a number."""

    _CSafeLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789"))
    _without_dates(_CSafeLoader)
    _Loader = _CSafeLoader
else:
    _Loader = _SafeLoader


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



#: Deepest nesting of mappings and lists a YAML file may have (the templates
#: nest 6 deep).
MAX_DEPTH = 64
#: Most nodes a document may hold with every alias expanded (the chair
#: template has about 400, a batch table of 1,000 people about 6,000).
MAX_NODES = 50_000
#: Schema errors looked at to report the first (in file order) and count the rest.
MAX_SCHEMA_ERRORS = 100
#: Largest YAML file read, bytes.
MAX_BYTES = MAX_FILE_BYTES["YAML"]
#: Longest mapping key, characters (keys are names: segments, joints, options).
MAX_KEY = 200
def _line_of_offset(text: str | bytes, offset: int) -> int:
    return (text[:offset].count(b"\n" if isinstance(text, bytes) else "\n")) + 1


def decode_text(data: bytes, source: str, what: str = "file") -> str:
    """UTF-8 ``data`` as text, or a RecipeError naming the first bad byte."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = _line_of_offset(data, e.start)
        msg = (
            f"{source}:{line}: not UTF-8 text: byte 0x{data[e.start]:02x} at byte offset {e.start}; "
            f"save the {what} as UTF-8"
        )
        raise RecipeError(msg) from None
    return text[1:] if text.startswith("\ufeff") else text


def read_text(path, what: str = "file", *, max_bytes: int = MAX_BYTES) -> str:
    """Read a UTF-8 text file a user gave, with one-line errors.

    Raises
    ------
    RecipeError
        Missing or unreadable file, not a regular file (a FIFO, a device),
        larger than ``max_bytes``, or not UTF-8 (see
        :func:`seatkit.io.read_user_file`).
    """
    path = Path(path)
    return decode_text(read_user_file(path, what, max_bytes=max_bytes, error=RecipeError), str(path), what)


def _check_events(loader, source: str) -> None:
    """Refuse over-deep nesting, alias bombs and self-referring aliases.

    One pass over the parser's events (which neither recurses nor builds
    anything): the size and height of every anchored node are recorded, so
    that an alias counts as the whole subtree it stands for.
    """
    # stack of [nodes so far, height of the subtree, anchor, line]
    stack: list[list] = [[0, 0, None, 0]]
    anchors: dict[str, tuple[int, int]] = {}
    open_anchors: set[str] = set()
    total = 0

    def add(size: int, height: int, line: int) -> None:
        nonlocal total
        top = stack[-1]
        top[0] += size
        top[1] = max(top[1], height)
        total += size
        if total > MAX_NODES:
            msg = (
                f"{source}:{line}: the document grows past {MAX_NODES} values once its aliases (*name) are "
                "expanded; seatkit refuses such alias bombs"
            )
            raise RecipeError(msg)
        if len(stack) + height > MAX_DEPTH + 1:
            msg = f"{source}:{line}: nested more than {MAX_DEPTH} levels deep; seatkit reads flatter files"
            raise RecipeError(msg)

    while loader.check_event():
        event = loader.get_event()
        line = event.start_mark.line + 1 if event.start_mark is not None else 0
        if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            if len(stack) > MAX_DEPTH:
                msg = f"{source}:{line}: nested more than {MAX_DEPTH} levels deep; seatkit reads flatter files"
                raise RecipeError(msg)
            if event.anchor is not None:
                open_anchors.add(event.anchor)
            stack.append([0, 0, event.anchor, line])
        elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            size, height, anchor, start = stack.pop()
            total -= size  # counted again, with the node itself, by add()
            add(size + 1, height + 1, start)
            if anchor is not None:
                open_anchors.discard(anchor)
                anchors[anchor] = (size + 1, height + 1)
        elif isinstance(event, yaml.ScalarEvent):
            add(1, 1, line)
            if event.anchor is not None:
                anchors[event.anchor] = (1, 1)
        elif isinstance(event, yaml.AliasEvent):
            if event.anchor in open_anchors:
                msg = f"{source}:{line}: alias *{clip(event.anchor, 30)} refers to a value that contains it"
                raise RecipeError(msg)
            size, height = anchors.get(event.anchor, (1, 1))  # unknown: the composer names it
            add(size, height, line)


def _syntax_error(e: yaml.YAMLError, text: str, source: str) -> RecipeError:
    if isinstance(e, yaml.reader.ReaderError):
        line = _line_of_offset(text, e.position)
        return RecipeError(f"{source}:{line}: not valid YAML: character U+{e.character:04X} is not allowed in YAML text")
    mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
    line = f":{mark.line + 1}" if mark is not None else ""
    problem = getattr(e, "problem", None) or str(e).splitlines()[0]
    return RecipeError(f"{source}{line}: not valid YAML: {clip(problem, 200)}")


def compose_yaml(text: str, *, source: str = "<string>"):
    """The node tree of YAML ``text`` (None if empty), within the limits above.

    For readers that walk the nodes themselves (poses); build scalars with
    :func:`scalar_value`.

    Raises
    ------
    RecipeError
        Syntax errors (with file and line), too deep, alias bombs.
    """
    for loader_class in (_Loader, _SafeLoader):
        try:
            loader = loader_class(text)
            try:
                _check_events(loader, source)
            finally:
                loader.dispose()
            loader = loader_class(text)
            try:
                return loader.get_single_node()
            finally:
                loader.dispose()
        except yaml.YAMLError as e:
            if loader_class is not _SafeLoader:
                # a syntax error: parse again with the pure-Python parser,
                # whose messages say more ("found character '\t' that cannot
                # start any token")
                continue
            raise _syntax_error(e, text, source) from None
    raise AssertionError("unreachable")


#: The scalar types seatkit reads from YAML: JSON's (null, booleans, numbers, text).
_PLAIN_TAGS = {f"tag:yaml.org,2002:{name}": name for name in ("null", "bool", "int", "float", "str")}


def _shown_tag(tag: str) -> str:
    return "!!" + tag[len("tag:yaml.org,2002:"):] if tag.startswith("tag:yaml.org,2002:") else tag


def scalar_value(node, source: str = "<string>") -> Any:
    """The Python value of a scalar node: JSON's types only (null, booleans, numbers, text).

    A date (``2001-02-30``) is read as the text it is; an explicit tag other
    than ``!!null``, ``!!bool``, ``!!int``, ``!!float``, ``!!str``
    (``!!timestamp``, ``!!binary``, ``!!python/...``) is refused.

    Raises
    ------
    RecipeError
        A tag seatkit does not read, or a value the tag cannot build (an
        integer of 5,000 digits, ``!!int x``), with the line.
    """
    line = node.start_mark.line + 1 if node.start_mark is not None else 0
    value = node.value if isinstance(node.value, str) else None
    kind = _PLAIN_TAGS.get(node.tag)
    if kind is None or value is None:
        msg = (
            f"{source}:{line}: cannot read the value {quote(value if value is not None else 'a collection')} tagged "
            f"{clip(_shown_tag(str(node.tag)), 60)}: seatkit reads null, true or false, numbers and text"
        )
        raise RecipeError(msg)
    try:
        # a fresh constructor each time: no state shared between threads
        constructor = yaml.constructor.SafeConstructor()
        return getattr(constructor, f"construct_yaml_{kind}")(node)
    except (yaml.YAMLError, ValueError, OverflowError, TypeError, AttributeError, IndexError) as e:
        problem = getattr(e, "problem", None) or str(e)
        msg = f"{source}:{line}: cannot read the value {quote(value)} as {kind}: {clip(problem, 120)}"
        raise RecipeError(msg) from None


_COLLECTION_TAGS = {yaml.MappingNode: "tag:yaml.org,2002:map", yaml.SequenceNode: "tag:yaml.org,2002:seq"}


def check_collection_tag(node, source: str = "<string>") -> None:
    """Refuse a mapping or list with a tag (``!!set``, ``!!omap``, ``!!timestamp {}``): seatkit reads JSON's types."""
    expected = _COLLECTION_TAGS.get(type(node))
    if expected is not None and node.tag != expected:
        what = "mapping" if isinstance(node, yaml.MappingNode) else "list"
        msg = (
            f"{source}:{node.start_mark.line + 1}: a {what} tagged {clip(_shown_tag(str(node.tag)), 60)}: "
            f"seatkit reads plain mappings and lists"
        )
        raise RecipeError(msg)


def _construct(node, path, lines, source):
    lines[path] = node.start_mark.line + 1
    check_collection_tag(node, source)
    if isinstance(node, yaml.MappingNode):
        out = {}
        for key_node, value_node in node.value:
            line = key_node.start_mark.line + 1
            key = scalar_value(key_node, source) if isinstance(key_node, yaml.ScalarNode) else None
            if not isinstance(key, (str, int, float, bool)) or key is None:
                shown = quote(key) if isinstance(key_node, yaml.ScalarNode) else "a mapping or list"
                msg = f"{source}:{line}: {format_path(path)}: mapping keys must be plain names, got {shown}"
                raise RecipeError(msg)
            key = str(key)
            if len(key) > MAX_KEY:
                msg = f"{source}:{line}: {format_path(path)}: a key of {len(key)} characters; keys are names of at most {MAX_KEY}"
                raise RecipeError(msg)
            if key in out:
                msg = f"{source}:{line}: key {quote(format_path(path + (key,)))} is given twice"
                raise RecipeError(msg)
            out[key] = _construct(value_node, path + (key,), lines, source)
            lines[path + (key,)] = line
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_construct(child, path + (i,), lines, source) for i, child in enumerate(node.value)]
    return scalar_value(node, source)


def parse_yaml(text: str, *, source: str = "<string>") -> Document:
    """Parse YAML text into a :class:`Document`.

    Raises
    ------
    RecipeError
        On a syntax error, with the file and line; on nesting deeper than
        :data:`MAX_DEPTH`, more than :data:`MAX_NODES` values with aliases
        expanded, a value that cannot be built, a key given twice.
    """
    node = compose_yaml(text, source=source)
    lines: dict = {}
    data = {} if node is None else _construct(node, (), lines, source)
    return Document(data, source, lines)


def load_yaml(path, what: str = "YAML file") -> Document:
    """Read (see :func:`read_text`) and parse (see :func:`parse_yaml`) a YAML file."""
    path = Path(path)
    return parse_yaml(read_text(path, what), source=str(path))


#: Largest magnitude of an integer a schema "number" or "integer" accepts.
MAX_INTEGER = 2**63 - 1


def _is_integer(checker, value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and abs(value) <= MAX_INTEGER


def _is_number(checker, value) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    return _is_integer(checker, value)


def _strict_validator():
    """Draft 2020-12 whose "integer" is a real integer (not ``1.0`` nor ``true``)
    and whose "number" is finite (not NaN, not infinite, no 5,000-digit integers)."""
    import jsonschema

    base = jsonschema.Draft202012Validator
    checker = base.TYPE_CHECKER.redefine_many({"integer": _is_integer, "number": _is_number})
    return jsonschema.validators.extend(base, type_checker=checker)


_VALIDATOR = None


def strict_validator(schema: dict):
    """A jsonschema validator of ``schema`` with seatkit's strict number types."""
    global _VALIDATOR
    if _VALIDATOR is None:
        _VALIDATOR = _strict_validator()
    return _VALIDATOR(schema)


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
        names = [_TYPE_NAMES.get(w, w) for w in want]
        if isinstance(inst, float) and not math.isfinite(inst) and ("number" in want or "integer" in want):
            names = ["a finite " + n[2:] if n.startswith("a ") else n for n in names]
        elif isinstance(inst, float) and "integer" in want and inst == int(inst):
            names = [n + " (no decimal point)" if w == "integer" else n for w, n in zip(want, names)]
        elif isinstance(inst, int) and not isinstance(inst, bool) and abs(inst) > MAX_INTEGER:
            return f"expected a number of at most {MAX_INTEGER}, got an integer of {len(str(abs(inst)))} digits"
        return f"expected {' or '.join(names)}, got {quote(inst)}"
    if v == "enum":
        return f"expected one of {', '.join(map(str, error.validator_value))}; got {quote(inst)}"
    if v == "required":
        missing = [k for k in error.validator_value if k not in inst]
        return f"missing required key {missing[0]!r}" if missing else error.message
    if v == "additionalProperties":
        allowed = sorted(error.schema.get("properties", {}))
        extra = sorted(set(inst) - set(allowed))
        return f"unknown key {quote(extra[0])}; expected one of {', '.join(allowed)}" if extra else error.message
    if v in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum"):
        op = {"minimum": ">=", "exclusiveMinimum": ">", "maximum": "<=", "exclusiveMaximum": "<"}[v]
        return f"expected a value {op} {error.validator_value}, got {quote(inst)}"
    if v in ("minItems", "maxItems"):
        word = "at least" if v == "minItems" else "at most"
        return f"expected {word} {error.validator_value} items, got {len(inst)}"
    if v in ("minLength", "maxLength") and isinstance(inst, str):
        word = "at least" if v == "minLength" else "at most"
        return f"expected {word} {error.validator_value} characters, got {len(inst)}"
    if v == "pattern" and isinstance(inst, str) and "\x00" in inst:
        return f"{quote(inst)} contains a NUL character"
    if v == "pattern":
        return f"{quote(inst)} does not match the expected form {error.validator_value!r}"
    return clip(error.message, 200)


def _locate(e) -> tuple:
    """(key path, error) to report for one jsonschema error."""
    import jsonschema

    path = tuple(e.absolute_path)
    # anyOf/oneOf: the most specific sub-error, preferring a branch whose type
    # matched (``lambda: 1e308`` is "too large", not "inf was expected")
    if e.context:
        typed = [c for c in e.context if c.validator not in ("type", "const", "enum")]
        e = jsonschema.exceptions.best_match(typed or e.context)
        path = tuple(e.absolute_path)
    if e.validator == "additionalProperties" and isinstance(e.instance, dict):
        extra = sorted(set(e.instance) - set(e.schema.get("properties", {})))
        if extra:
            path = path + (extra[0],)
    return path, e


def validate(doc: Document, schema: dict) -> None:
    """Check ``doc.data`` against a JSON schema (with :func:`strict_validator`).

    Raises
    ------
    RecipeError
        On one line: the first problem (in file order) as
        ``file:line: key.path: what was expected``, and how many more there are.
    """
    validator = strict_validator(schema)
    # a list of 50,000 wrong values has 50,000 errors: look at the first hundred
    located = [_locate(e) for e in itertools.islice(validator.iter_errors(doc.data), MAX_SCHEMA_ERRORS + 1)]
    if not located:
        return
    located.sort(key=lambda pe: (doc.line(pe[0]) or 0, list(map(str, pe[0]))))
    path, e = located[0]
    line = f"{doc.where(path)}: {_describe(e)}"
    if len(located) > 1:
        more = len(located) - 1
        count = f"{MAX_SCHEMA_ERRORS} or more" if more >= MAX_SCHEMA_ERRORS else str(more)
        line += f" (and {count} more problem{'s' if more > 1 else ''})"
    raise RecipeError(line)
