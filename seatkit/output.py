"""A build's output folder: its name, its hold on it, staging, and the clean-up of killed builds.

A build writes into a staging folder beside its target (``.X.staging-*``) and
moves it onto the target at the end (:func:`finish_output`, in :func:`staging_folder`:
the previous output is first moved into ``.X.old-*/X``, then the staging
folder onto ``X``, then ``.X.old-*`` is deleted). A build killed on the way
(``kill -9``, a power cut) leaves one of those folders behind.

:func:`claim_output` is held for the whole of a writing build, from before
the design is computed to the final rename:

- it takes an exclusive lock on ``.X.lock`` beside the target (``flock``;
  the kernel releases it when the holder dies, however it dies). A second
  build into the same folder is refused at once with a message naming the
  holder's process, instead of computing a design whose result would then
  be silently discarded;
- holding the lock, it knows that no other build is writing ``X``, so any
  ``.X.staging-*`` or ``.X.old-*`` left beside it is from a killed build:
  a previous output left in ``.X.old-*/X`` while ``X`` is missing (killed
  between the two renames) is moved back to ``X`` first, then those folders
  are deleted;
- it checks that the folder can be written (the parent can be created and
  written into, an existing target is writable and holds a seatkit run
  unless ``overwrite``), so that a read-only folder or one without
  permission is one clear line naming the path, before any geometry work.

:func:`output_error` turns an :class:`OSError` met while writing (a full
disk, a folder made read-only meanwhile) into the same kind of one-line
error. Platforms without ``fcntl`` (Windows), and file systems that refuse
locks, get the checks and the clean-up of folders older than
:data:`STALE_AGE_S` but no lock.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import json
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Iterator, Mapping

from seatkit.errors import SeatkitError
from seatkit.io import RUN_MARKER, is_complete

try:  # POSIX
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

#: Without a lock (no ``fcntl``), leftovers older than this are taken as stale, s.
STALE_AGE_S = 24 * 3600.0


class OutputError(SeatkitError):
    """The output folder cannot be written, or another build holds it."""


def output_error(error: OSError, target: Path) -> OutputError:
    """One line for an OS error met while writing the output folder ``target``."""
    what = error.strerror or str(error)
    where = f" (writing {Path(error.filename).name})" if getattr(error, "filename", None) else ""
    return OutputError(f"cannot write the output folder {target}: {what}{where}")


def leftovers(target: Path) -> tuple[list[Path], list[Path]]:
    """The ``.X.staging-*`` and ``.X.old-*`` folders beside ``target``."""
    target = Path(target)
    stem = glob.escape(f".{target.name}")
    parent = target.parent
    return sorted(parent.glob(f"{stem}.staging-*")), sorted(parent.glob(f"{stem}.old-*"))


def recover(target: Path, *, locked: bool = True) -> list[str]:
    """Restore or delete what killed builds left beside ``target``; say what was done.

    Call only while holding the output's lock (:func:`claim_output`), when
    no other build can be using those folders. Without a lock
    (``locked=False``) only folders older than :data:`STALE_AGE_S` are touched.
    """
    target = Path(target)
    staging, old = leftovers(target)
    now = time.time()

    def stale(p: Path) -> bool:
        if locked:
            return True
        with contextlib.suppress(OSError):
            return now - p.stat().st_mtime > STALE_AGE_S
        return False

    done = []
    for folder in old:
        if not stale(folder):
            continue
        previous = folder / target.name
        if not target.exists() and previous.is_dir() and is_complete(previous):
            os.replace(previous, target)  # killed between the two renames: put the previous output back
            done.append(f"restored the previous output of {target} from {folder.name}")
        shutil.rmtree(folder, ignore_errors=True)
        done.append(f"removed {folder}")
    for folder in staging:
        if stale(folder):
            shutil.rmtree(folder, ignore_errors=True)
            done.append(f"removed {folder}")
    return done


def _check_parent(target: Path) -> None:
    parent = target.parent
    if not os.access(parent, os.W_OK | os.X_OK):
        msg = f"cannot write the output folder {target}: no permission to write into {parent}"
        raise OutputError(msg)


def check_writable(target: Path, *, overwrite: bool) -> None:
    """Refuse, in one line naming the path, an output folder this build could not replace."""
    target = Path(target)
    _check_parent(target)
    if not target.exists():
        return
    if not target.is_dir():
        msg = f"output path {target} exists and is not a folder"
        raise OutputError(msg)
    if not os.access(target, os.W_OK | os.X_OK):
        msg = f"cannot replace the output folder {target}: it is read-only (no write permission); make it writable or choose another --out"
        raise OutputError(msg)
    if not overwrite and not (target / RUN_MARKER).exists() and any(target.iterdir()):
        msg = f"output folder {target} holds files that seatkit did not write; choose another --out or pass --overwrite"
        raise OutputError(msg)


def _lock_path(target: Path) -> Path:
    return target.parent / f".{target.name}.lock"


def _holder(fd: int) -> str:
    with contextlib.suppress(OSError, ValueError):
        pid = int(os.pread(fd, 32, 0).split()[0])
        return f" (process {pid})"
    return ""


def _lock(target: Path) -> int | None:
    """Take the exclusive lock of ``target``; its file descriptor (None without fcntl)."""
    if fcntl is None:  # pragma: no cover - Windows
        return None
    path = _lock_path(target)
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            raise OutputError(f"cannot write the output folder {target}: {e.strerror} ({path})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            msg = (
                f"another seatkit build{holder} is writing the output folder {target}; "
                "wait for it to finish or choose another --out"
            )
            raise OutputError(msg) from None
        except OSError:  # a file system without locks (some network mounts): build unlocked
            os.close(fd)
            with contextlib.suppress(OSError):
                os.unlink(path)
            return None
        # A build that just finished unlinks the lock file: make sure the file
        # locked is still the one at that name, or try again on the new one.
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            with contextlib.suppress(OSError):  # the holder's id is for messages only (a full disk may refuse it)
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
            return fd
        os.close(fd)


@contextlib.contextmanager
def claim_output(target, *, overwrite: bool = False) -> Iterator[list[str]]:
    """Hold the output folder ``target`` for one build (see the module docstring).

    Yields
    ------
    list of str
        What was recovered from killed builds (restored or removed folders).

    Raises
    ------
    OutputError
        Another build holds the folder, or it cannot be written.
    """
    target = Path(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(f"cannot create the output folder {target}: {e.strerror} ({e.filename or target.parent})") from None
    _check_parent(target)
    fd = _lock(target)
    try:
        done = recover(target, locked=fd is not None)
        check_writable(target, overwrite=overwrite)
        yield done
    finally:
        if fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(_lock_path(target))
            os.close(fd)


def finish_output(staging: Path, target: Path, *, overwrite: bool) -> None:
    """Move a finished staging folder onto ``target``.

    A previous seatkit run in ``target`` is replaced; a folder with other
    files is refused unless ``overwrite``.
    """
    if target.exists():
        check_writable(target, overwrite=overwrite)  # checked before the design too (claim_output)
        trash = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
        os.replace(target, trash / target.name)
        os.replace(staging, target)
        shutil.rmtree(trash, ignore_errors=True)
    else:
        os.replace(staging, target)


@contextlib.contextmanager
def staging_folder(target, *, overwrite: bool = False) -> Iterator[Path]:
    """A fresh staging folder beside ``target``, moved onto it when the block ends without error.

    On an error the staging folder is deleted and ``target`` is left as it
    was; an :class:`OSError` (a full disk, a folder made read-only
    meanwhile) becomes one :class:`OutputError` line naming the folder.
    """
    target = Path(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.staging-", dir=target.parent))
    except OSError as e:
        raise output_error(e, target) from e
    mask = os.umask(0)
    os.umask(mask)
    try:
        os.chmod(staging, 0o777 & ~mask)  # mkdtemp makes 0700 folders
        yield staging
        finish_output(staging, target, overwrite=overwrite)
    except OSError as e:
        shutil.rmtree(staging, ignore_errors=True)
        raise output_error(e, target) from e
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


#: Longest default output folder name; longer ones end in a hash of the whole name.
MAX_DESIGN_NAME = 96


def design_name(recipe: Mapping) -> str:
    """A folder name that tells one design from another: template, then each person.

    Each person is their ``name`` if the recipe gives one, else their pose
    (a library name, or a pose file's stem, with ``-frameN`` for a BVH),
    followed by the body when it is not the default (``-default-female``,
    a body file's stem) and the mass when one is given (``-60kg``); people
    are joined by ``+`` in seat order::

        chair-upright-sitting
        chair-reclined-sitting-default-female-60kg
        bench-upright-sitting+reclined-sitting+crossed-legs-knees

    Other body parameters add a short hash of them, so that two designs
    for different bodies never share a default folder.
    """
    from seatkit.recipe import DEFAULT_BODY_MODEL, looks_like_path

    people = []
    for entry in recipe["bodies"]:
        if entry.get("name"):
            people.append(str(entry["name"]))
            continue
        pose = str(entry["pose"])
        part = Path(pose).stem if looks_like_path(pose) else pose
        if pose.lower().endswith(".bvh"):
            part += f"-frame{int(entry.get('frame') or 0)}"
        params = dict(entry.get("params") or {})
        model = entry.get("model", DEFAULT_BODY_MODEL)
        if model == "file":
            part += "-" + Path(str(params.pop("path", "body"))).stem
        elif model != DEFAULT_BODY_MODEL:
            part += f"-{model}"
        mass = params.pop("mass", None)
        if isinstance(mass, (int, float)):
            part += f"-{float(mass):g}kg"
        if params:
            part += "-" + hashlib.sha256(json.dumps(params, sort_keys=True, default=str).encode()).hexdigest()[:6]
        people.append(part)
    name = f"{recipe['template']}-{'+'.join(people)}"
    name = "".join(c if c.isalnum() or c in "-_.+" else "-" for c in name).strip("-.") or "design"
    if len(name) > MAX_DESIGN_NAME:
        digest = hashlib.sha256(name.encode()).hexdigest()[:8]
        name = f"{name[: MAX_DESIGN_NAME - 9]}-{digest}"
    return name


def output_target(recipe: Mapping) -> Path:
    """The output folder of a recipe (default ``seatkit-out/`` + :func:`design_name`)."""
    return Path(recipe["output"] or Path("seatkit-out") / design_name(recipe))


def save_unsupported(error, recipe: Mapping) -> None:
    """Write what could and could not be supported beside the output folder.

    ``error`` is an :class:`~seatkit.errors.UnsupportedPoseError`. The file
    is ``<output>-unsupported.json`` (not inside the folder: no design was
    made, so no output folder is created); its path is appended to the
    error's message.
    """
    from seatkit.io import jsonable, write_text_atomic

    target = output_target(recipe)
    path = target.parent / f"{target.name}-unsupported.json"
    data = {
        "error": str(error),
        "unsupported_parts": error.parts,
        "diagnostics": jsonable(error.diagnostics),
        "recipe": jsonable(dict(recipe)),
    }
    write_text_atomic(path, json.dumps(data, indent=1, default=str) + "\n")
    error.args = (f"{error}; diagnostics saved to {path}",)
