"""How a user's values and key paths are shown in one-line messages.

:func:`clip` puts text on one line and shortens it, :func:`quote` does the
same to a value's ``repr``, :func:`format_path` writes a key path the way a
user finds it in the file (``faces[4].segment``). The errors
(:class:`seatkit.errors.ParamError`) and the YAML reader
(:mod:`seatkit.yamlio`) both use them; nothing here imports seatkit.
"""

from __future__ import annotations

from typing import Any, Iterable

__all__ = ["MAX_QUOTE", "clip", "quote", "format_path"]

#: Longest quotation of a user's value in a message, characters.
MAX_QUOTE = 60


def clip(text: str, limit: int = MAX_QUOTE) -> str:
    """``text`` on one line, shortened to about ``limit`` characters for messages."""
    text = " ".join(str(text).split())
    if len(text) <= limit:
        return text
    return f"{text[: max(limit - 20, 10)]}... ({len(text)} characters)"


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
