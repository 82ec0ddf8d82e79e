"""Atomic output files and output folders.

A build never leaves a half-written file that looks complete: every file is
written to a temporary name in the same folder and renamed into place
(:func:`os.replace` is atomic on POSIX and Windows). A finished output folder
records its run in ``.seatkit-run`` (:func:`mark_complete`); the pipeline
writes a build into a staging folder and moves it onto the target only at
the end (:func:`seatkit.output.staging_folder`), so runs are never mixed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import math
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np


RUN_MARKER = ".seatkit-run"


def jsonable(value):
    """``value`` as plain JSON data, the way report.json and design.npz write it.

    Mappings (a Recipe too) become dicts with string keys, tuples and arrays
    lists, numpy scalars Python numbers, other dataclasses dicts of their fields;
    non-finite floats become strings (``"inf"``, ``"nan"``: JSON has no
    such numbers). Anything else is returned as it is.
    """
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return jsonable(value.item())
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return jsonable({f.name: getattr(value, f.name) for f in dataclasses.fields(value)})
    return value


def _umask_mode() -> int:
    """The permission bits a plain ``open()`` would give a new file."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


@contextlib.contextmanager
def atomic_write(path, mode: str = "wb"):
    """Open a temporary file beside ``path``; rename it onto ``path`` on success.

    Parameters
    ----------
    path : str or Path
        Final file name.
    mode : str
        ``"wb"`` or ``"w"`` (text, UTF-8).

    Yields
    ------
    file object
        Write to it; on an exception the temporary file is deleted and
        ``path`` is left untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(fd, mode, encoding=encoding) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _umask_mode())  # mkstemp makes 0600 files
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_bytes_atomic(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and return the path."""
    with atomic_write(path, "wb") as fh:
        fh.write(data)
    return Path(path)


def write_text_atomic(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically and return the path."""
    return write_bytes_atomic(path, text.encode("utf-8"))


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path`` for writers that want a file name.

    Libraries such as trimesh or usd-core write to a name, not a handle: give
    them the yielded path; it is renamed onto ``path`` when the block ends
    without an exception. The temporary name keeps the final suffix so that
    format detection by extension works.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, _umask_mode())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def mark_complete(directory, *, run_id: str, files: dict) -> None:
    """Record that ``directory`` holds a finished run and which files it wrote."""
    data = {"run": run_id, "complete": True, "files": {k: str(v) for k, v in files.items()}}
    write_text_atomic(Path(directory) / RUN_MARKER, json.dumps(data, indent=1) + "\n")


def is_complete(directory) -> bool:
    """Whether ``directory`` holds a finished run whose listed files all exist."""
    marker = Path(directory) / RUN_MARKER
    try:
        data = json.loads(marker.read_text())
    except (OSError, ValueError):
        return False
    if not data.get("complete"):
        return False
    return all((Path(directory) / Path(p).name).exists() for p in data.get("files", {}).values())


def _plain(value):
    # json.dumps' hook for what is not JSON already: a checked Recipe as its
    # plain sections (Recipe.to_dict), anything else as its text
    to_dict = getattr(type(value), "to_dict", None)
    return to_dict(value) if callable(to_dict) else str(value)


def recipe_id(recipe) -> str:
    """A short stable hash of a recipe, a plain mapping or a checked Recipe (identifies a run's inputs)."""
    text = json.dumps(recipe, sort_keys=True, default=_plain)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
