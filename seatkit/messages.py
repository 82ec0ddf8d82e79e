"""How a user's values and key paths are shown in one-line messages.

:func:`clip` puts text on one line and shortens it, :func:`quote` does the
same to a value's ``repr``, :func:`format_path` writes a key path the way a
user finds it in the file (``faces[4].segment``). The errors
(:class:`seatkit.errors.ParamError`) and the YAML reader
(:mod:`seatkit.yamlio`) both use them; nothing here imports seatkit.
"""

from __future__ import annotations

from typing import Any, Iterable

__all__ = ["MAX_MESSAGE", "MAX_QUOTE", "clip", "quote", "format_path", "one_line"]

#: Longest quotation of a user's value in a message, characters.
MAX_QUOTE = 60
#: Longest message seatkit prints for a user error, characters (docs/robustness.md).
MAX_MESSAGE = 500


def clip(text: str, limit: int = MAX_QUOTE) -> str:
    """``text`` on one line, shortened to about ``limit`` characters for messages."""
    text = " ".join(str(text).split())
    if len(text) <= limit:
        return text
    return f"{text[: max(limit - 20, 10)]}... ({len(text)} characters)"


def _cut_at_word(text: str, limit: int, *, from_end: bool = False) -> str:
    """At most ``limit`` characters of ``text`` from its start (or end), ending at a word boundary."""
    if len(text) <= limit:
        return text
    if from_end:
        part = text[len(text) - limit :]
        space = part.find(" ")
        return part[space + 1 :] if 0 <= space < limit // 2 else part
    part = text[:limit]
    space = part.rfind(" ")
    return part[:space] if space > limit // 2 else part


def one_line(text: str, limit: int = MAX_MESSAGE) -> str:
    """A message on one line of at most ``limit`` characters, summarised if longer.

    Line breaks become spaces. A longer message keeps its beginning (the file,
    line and field) and its end (what was expected), cut at word boundaries,
    and says how much was left out between them::

        c.usda: faceVertexIndices: [0, 1, 2, ... (5,912 characters left out) ..., 3]: expected ...
    """
    text = " ".join(str(text).split())
    if len(text) <= limit:
        return text
    # the marker's width is bounded by the digits of len(text); keep 2/3 for the head
    marker_room = len(f" ... ({len(text):,} characters left out) ... ")
    room = max(limit - marker_room, 20)
    head = _cut_at_word(text, room * 2 // 3)
    tail = _cut_at_word(text, room - len(head), from_end=True)
    left_out = len(text) - len(head) - len(tail)
    return f"{head} ... ({left_out:,} characters left out) ... {tail}"[:limit]


def quote(value: Any, limit: int = MAX_QUOTE) -> str:
    """``repr(value)``, shortened to about ``limit`` characters for messages."""
    return clip(repr(value), limit)


def format_path(path: Iterable) -> str:
    """``("faces", 4, "segment")`` -> ``faces[4].segment``."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            text = str(part)
            if not text.isprintable() or len(text) > 60:
                text = quote(part, 60)  # a key of control characters or a huge key, shown escaped and short
            out += ("." if out else "") + text
    return out or "(top level)"
