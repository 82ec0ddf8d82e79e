"""Reading a user's files within caps; atomic output files and output folders.

Every file a user gives is opened through :func:`read_user_file` (or checked
by :func:`check_user_file` before a library opens it by name): only regular
files are read (a FIFO, a device such as ``/dev/zero`` or a socket, also
behind a symlink, is refused before anything blocks), and never past the cap
of its kind in :data:`MAX_FILE_BYTES`. ``.npz`` files are opened by
:func:`load_npz`, which also caps what their members unpack to.

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
import io
import math
import os
import stat
import tempfile
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from seatkit.errors import InputError
from seatkit.messages import clip

_MB = 1024 * 1024

#: Largest file of each kind read from a user, bytes; checked before parsing.
MAX_FILE_BYTES = {
    "YAML": 16 * _MB,  # recipes, templates, poses, name maps, batch tables
    "CSV": 16 * _MB,  # batch tables
    "BVH": 100 * _MB,  # about 10 minutes of a 60-joint capture at 60 fps
    "glTF": 256 * _MB,  # a .glb or .gltf and each of its buffers
    "OBJ": 64 * _MB,  # a cage of about a million faces
    "USD": 64 * _MB,
    "npz": 128 * _MB,  # body rigs and design.npz, compressed
}
#: Most bytes the arrays of one ``.npz`` may unpack to, and most arrays in it.
MAX_NPZ_UNPACKED = 1024 * _MB
MAX_NPZ_MEMBERS = 1000
#: npz member dtypes seatkit reads: booleans, integers, floats, text.
_NPZ_KINDS = "biufUS"


def _file_kind(mode: int) -> str:
    for test, name in (
        (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def _check_stat(path: Path, st: os.stat_result, what: str, max_bytes: int, error) -> None:
    if not stat.S_ISREG(st.st_mode):
        msg = f"{path}: is {_file_kind(st.st_mode)}, expected a {what} (a regular file)"
        raise error(msg)
    if st.st_size > max_bytes:
        msg = f"{path}: {st.st_size:,} bytes, larger than the {max_bytes // _MB} MB seatkit reads for a {what}"
        raise error(msg)


def _os_error(path: Path, e: OSError, what: str, error):
    if isinstance(e, FileNotFoundError):
        return error(f"{path}: file not found (no such {what})")
    if isinstance(e, IsADirectoryError):
        return error(f"{path}: is a folder, expected a {what}")
    return error(f"{path}: cannot read the {what}: {clip(e.strerror or e, 120)}")


def check_user_file(path, what: str, *, max_bytes: int, error=InputError) -> Path:
    """``path`` if it is a regular file of at most ``max_bytes``, for a library that opens it by name.

    Raises ``error`` (default :class:`~seatkit.errors.InputError`) with one
    line naming the file: missing, a folder, a FIFO or device (also behind a
    symlink), larger than the cap, a name the OS refuses.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except (OSError, ValueError) as e:  # ValueError: a NUL byte in the name
        if isinstance(e, ValueError):
            raise error(f"{clip(str(path), 120)}: not a usable file name ({e})") from None
        raise _os_error(path, e, what, error) from None
    _check_stat(path, st, what, max_bytes, error)
    return path


def read_user_file(path, what: str, *, max_bytes: int, error=InputError) -> bytes:
    """The bytes of a user's file: a regular file of at most ``max_bytes``.

    The file is opened without blocking and checked on its open descriptor
    (so a FIFO put in its place after a check is refused too), then at most
    ``max_bytes + 1`` bytes are read (a file growing while it is read is
    refused as well). Errors as :func:`check_user_file`.
    """
    path = Path(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
    except ValueError as e:
        raise error(f"{clip(str(path), 120)}: not a usable file name ({e})") from None
    except OSError as e:
        raise _os_error(path, e, what, error) from None
    try:
        _check_stat(path, os.fstat(fd), what, max_bytes, error)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = fh.read(max_bytes + 1)
    except OSError as e:
        raise _os_error(path, e, what, error) from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        msg = f"{path}: larger than the {max_bytes // _MB} MB seatkit reads for a {what}"
        raise error(msg)
    return data


def _npz_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path, what: str, error) -> np.ndarray:
    """One array of an npz, its header checked before any data is unpacked."""
    name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
    with zf.open(info) as fh:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
        elif version == (2, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        else:
            msg = f"{path}: {clip(name)}: .npy format version {version}, expected 1.0 or 2.0"
            raise error(msg)
        if dtype.kind not in _NPZ_KINDS or dtype.fields is not None or dtype.subdtype is not None:
            msg = f"{path}: {clip(name)}: arrays of {clip(str(dtype))}; expected numbers or text"
            raise error(msg)
        count = math.prod(shape)
        if count * dtype.itemsize > info.file_size:
            msg = (
                f"{path}: {clip(name)}: its header promises {count:,} values of {dtype.itemsize} bytes, "
                f"more than the {info.file_size:,} bytes stored"
            )
            raise error(msg)
        data = fh.read(count * dtype.itemsize)
    if len(data) != count * dtype.itemsize:
        msg = f"{path}: {clip(name)}: truncated array ({len(data):,} of {count * dtype.itemsize:,} bytes)"
        raise error(msg)
    array = np.frombuffer(data, dtype=dtype, count=count) if count else np.zeros(0, dtype)
    return array.reshape(shape, order="F" if fortran else "C").copy()


def load_npz(path, what: str, *, max_bytes: int = MAX_FILE_BYTES["npz"], error=InputError) -> dict[str, np.ndarray]:
    """The arrays of a user's ``.npz`` file, name -> array, within caps.

    At most ``max_bytes`` on disk, :data:`MAX_NPZ_MEMBERS` arrays unpacking to
    at most :data:`MAX_NPZ_UNPACKED` bytes, each a plain array of numbers or
    text (no pickled objects, no structured types) whose header agrees with
    its size. Raises ``error`` with one line naming the file for anything
    else (a file that is not a zip, a corrupt member, a CRC mismatch).
    """
    path = Path(path)
    data = read_user_file(path, what, max_bytes=max_bytes, error=error)
    arrays: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            infos = zf.infolist()
            if len(infos) > MAX_NPZ_MEMBERS:
                msg = f"{path}: {len(infos):,} arrays; a {what} has at most {MAX_NPZ_MEMBERS}"
                raise error(msg)
            unpacked = sum(i.file_size for i in infos)
            if unpacked > MAX_NPZ_UNPACKED:
                msg = f"{path}: unpacks to {unpacked:,} bytes, more than the {MAX_NPZ_UNPACKED // _MB} MB seatkit reads"
                raise error(msg)
            for info in infos:
                name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                if name in arrays:
                    msg = f"{path}: array {clip(name)} is stored twice"
                    raise error(msg)
                arrays[name] = _npz_member(zf, info, path, what, error)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, EOFError, OSError, ValueError,
            NotImplementedError, RuntimeError, KeyError, TypeError, OverflowError, SyntaxError, RecursionError,
            MemoryError) as e:
        # what zipfile and numpy's header parser raise for damaged data (a bad
        # header is a SyntaxError or ValueError of ast.literal_eval)
        msg = f"{path}: not a seatkit {what} ({clip(f'{type(e).__name__}: {e}', 160)})"
        raise error(msg) from None
    return arrays


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
