"""Work that runs beside the build: in a forked child process, or on a thread.

Why processes: a build is Python driving numpy and scipy on small arrays, so
two threads of one process mostly wait for each other's GIL. Measured on 2
cores: the ``optimize`` refiner takes 0.11 s alone but 0.41 s while the
baseline is fitted on a second thread. A child made with ``fork`` after the
inputs exist runs truly in parallel and shares them copy-on-write: nothing is
pickled on the way in, and only the (small) result comes back, pickled,
through a pipe.

Why not everywhere: ``fork`` is used only on Linux. macOS has ``fork``, but a
process that has loaded Apple's system libraries (Accelerate, via numpy) may
crash in a forked child, which is why Python's default there is ``spawn``;
Windows has no ``fork`` at all. ``spawn`` would start a fresh interpreter,
import numpy and scipy again (~1 s) and pickle the inputs, which costs more
than it saves, so on those platforms (and when the caller says so, e.g. batch
workers that already keep every core busy) the work runs on a thread instead,
with the same results.

The child leaves through :func:`os._exit`: it never runs the parent's
``atexit`` handlers, ``finally`` blocks or buffered output a second time.
Errors raised in the child are re-raised in the parent with their type,
message and attributes (a :class:`~seatkit.errors.SeatkitError` stays one, so
the command line prints it as the usual one-line message), with the child's
traceback attached as a note. Every child is reaped: :meth:`Background.result`
waits for it, :meth:`Background.close` stops and reaps one whose result is no
longer wanted (and waits for a thread, which cannot be stopped).
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import threading
import traceback
from typing import Any, Callable

from seatkit.errors import SeatkitError

__all__ = ["Background", "can_fork"]


def can_fork() -> bool:
    """Whether background work may run in a forked child process (Linux only; see the module docstring)."""
    return hasattr(os, "fork") and sys.platform.startswith("linux")


def _portable_error(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else the nearest thing that does (same message)."""
    try:
        pickle.loads(pickle.dumps(exc, protocol=pickle.HIGHEST_PROTOCOL))
        return exc
    except Exception:  # noqa: BLE001 - any failure to round-trip
        cls = SeatkitError if isinstance(exc, SeatkitError) else RuntimeError
        return cls(f"{type(exc).__name__}: {exc}" if cls is RuntimeError else str(exc))


class Background:
    """``fn(*args)`` started now, in a forked child process or on a thread.

    Parameters
    ----------
    fn : callable
        Its return value must be picklable when it runs in a process.
    *args
        Passed as they are (a forked child sees the parent's objects).
    name : str
        Names the work in error messages and the thread.
    process : bool
        Run in a forked child (only where :func:`can_fork`); otherwise on a
        thread.
    """

    def __init__(self, fn: Callable[..., Any], *args: Any, name: str, process: bool = True):
        self.name = name
        self.process = bool(process) and can_fork()
        self._done = False
        self._value: Any = None
        self._error: BaseException | None = None
        self._pid: int | None = None
        self._fd: int | None = None
        self._thread: threading.Thread | None = None
        if self.process:
            self._fork(fn, args)
        else:
            self._thread = threading.Thread(target=self._run_here, args=(fn, args), name=f"seatkit-{name}")
            self._thread.start()

    # ------------------------------------------------------------------ thread
    def _run_here(self, fn, args) -> None:
        try:
            self._value = fn(*args)
        except BaseException as exc:  # noqa: BLE001 - handed to result()
            self._error = exc

    # ----------------------------------------------------------------- process
    def _fork(self, fn, args) -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()  # or the child would hold (and never write) a copy of pending output
            except (AttributeError, ValueError, OSError):
                pass
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: compute, send, leave without running any of the parent's clean-up
            status = 0
            try:
                os.close(r)
                try:
                    payload = pickle.dumps((True, fn(*args)), protocol=pickle.HIGHEST_PROTOCOL)
                except BaseException as exc:  # noqa: BLE001 - sent to the parent
                    tb = "".join(traceback.format_exception(exc))
                    payload = pickle.dumps((False, _portable_error(exc), tb), protocol=pickle.HIGHEST_PROTOCOL)
                with os.fdopen(w, "wb") as pipe:
                    pipe.write(payload)
            except BaseException:  # noqa: BLE001 - e.g. the parent went away (broken pipe)
                status = 1
            finally:
                os._exit(status)
        os.close(w)
        self._pid, self._fd = pid, r

    def _collect(self) -> None:
        """Read the child's answer to the end, then reap it."""
        chunks = []
        with os.fdopen(self._fd, "rb") as pipe:
            self._fd = None
            while chunk := pipe.read(1 << 20):
                chunks.append(chunk)
        _, status = os.waitpid(self._pid, 0)
        self._pid = None
        data = b"".join(chunks)
        if not data:
            how = (
                f"was killed by signal {os.WTERMSIG(status)}"
                if os.WIFSIGNALED(status)
                else f"exited with status {os.waitstatus_to_exitcode(status)}"
            )
            self._error = RuntimeError(f"the {self.name} process {how} before sending its result")
            return
        answer = pickle.loads(data)
        if answer[0]:
            self._value = answer[1]
        else:
            self._error = answer[1]
            self._error.add_note(f"(raised in the {self.name} process)\n{answer[2]}")

    # ------------------------------------------------------------------ public
    def result(self) -> Any:
        """Wait for the work and return its value, or raise its error."""
        if not self._done:
            if self._thread is not None:
                self._thread.join()
            else:
                try:
                    self._collect()
                finally:
                    self.close()
            self._done = True
        if self._error is not None:
            raise self._error
        return self._value

    def close(self) -> None:
        """Stop a child whose result is not wanted, and reap it (idempotent).

        A thread cannot be stopped: this waits for it to finish, so that no
        work of a finished build goes on in the background.
        """
        if self._thread is not None:
            self._thread.join()
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self._pid is not None:
            try:
                os.kill(self._pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            os.waitpid(self._pid, 0)
            self._pid = None

    def __enter__(self) -> "Background":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
