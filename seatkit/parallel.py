"""Work that runs beside the build: in a forked child process, or on a thread.

Why processes: a build is Python driving numpy and scipy on small arrays, so
two threads of one process mostly wait for each other's GIL. Measured on 2
cores: the ``optimize`` refiner takes 0.11 s alone but 0.41 s while the
baseline is fitted on a second thread. A child made with ``fork`` after the
inputs exist runs truly in parallel and shares them copy-on-write: nothing is
pickled on the way in, and only the result comes back, pickled, through a
pipe. A child can also be started *before* its input exists (``inbox``): it
gets ready (imports what it needs) while the parent computes, then receives
the input, pickled, through a second pipe.

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
longer wanted (and waits for a thread, which cannot be stopped). A child ends
with its parent even when the parent is killed outright (``kill -9``): the
kernel sends it SIGKILL then (``prctl(PR_SET_PDEATHSIG)``, Linux).
"""

from __future__ import annotations

import os
import pickle
import queue
import signal
import struct
import sys
import threading
import traceback
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, Callable, Iterator

from seatkit.errors import SeatkitError

__all__ = ["Background", "can_fork", "forking", "forking_allowed"]

_PROTOCOL = pickle.HIGHEST_PROTOCOL

#: Whether the running build lets its parts fork (see :func:`forking`).
_FORKING: ContextVar[bool] = ContextVar("seatkit_forking", default=False)


def can_fork() -> bool:
    """Whether background work may run in a forked child process (Linux only; see the module docstring)."""
    return hasattr(os, "fork") and sys.platform.startswith("linux")


@contextmanager
def forking_allowed(allowed: bool) -> Iterator[None]:
    """Let the code run inside (a build's stages, its exporters) fork child processes, or not."""
    token = _FORKING.set(bool(allowed) and can_fork())
    try:
        yield
    finally:
        _FORKING.reset(token)


def forking() -> bool:
    """Whether the running code may split work into forked child processes.

    True only inside :func:`forking_allowed` (a build with ``processes``
    on) on a platform that forks safely: a component called outside a build,
    or from a batch worker that already keeps every core busy, works in one
    process.
    """
    return _FORKING.get()


#: prctl(2) option: the signal a process gets when its parent dies (Linux).
_PR_SET_PDEATHSIG = 1
_PRCTL = None


def _prctl():
    """libc's ``prctl`` (looked up once, in the parent: the child should not load libraries)."""
    global _PRCTL
    if _PRCTL is None:
        try:
            import ctypes

            _PRCTL = ctypes.CDLL(None, use_errno=True).prctl
        except (OSError, AttributeError):  # not glibc/musl Linux
            _PRCTL = False
    return _PRCTL


def _die_with_parent(parent: int) -> None:
    """Have the kernel kill this forked child when its parent dies, however it dies.

    A build killed with ``kill -9`` cannot stop its helpers itself; with
    ``PR_SET_PDEATHSIG`` they end with it instead of finishing their work
    (and holding the build's output lock) for nothing. The request is checked
    against a parent that died before it was made.
    """
    prctl = _prctl()
    if prctl:
        prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:
        os._exit(1)


def _portable_error(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else the nearest thing that does (same message)."""
    try:
        pickle.loads(pickle.dumps(exc, protocol=_PROTOCOL))
        return exc
    except Exception:  # noqa: BLE001 - any failure to round-trip
        if isinstance(exc, SeatkitError):
            return SeatkitError(str(exc))
        return RuntimeError(f"{type(exc).__name__}: {exc}")


# Messages on the pipes are length-prefixed rather than ended by closing the
# pipe: a child forked later (the baseline, half of the PNGs) holds copies of
# the parent's open pipe ends until it exits, so end-of-file can come late.
_HEADER = struct.Struct("<Q")


def _read_message(fd: int) -> bytes | None:
    """One message from a pipe, then close it; None if the writer closed it without sending."""
    with os.fdopen(fd, "rb") as pipe:
        head = pipe.read(_HEADER.size)
        if len(head) < _HEADER.size:
            return None
        (size,) = _HEADER.unpack(head)
        data = pipe.read(size)
    if len(data) < size:
        return None
    return data


def _write_message(fd: int, data: bytes) -> None:
    """Write one message to a pipe and close it (quietly if the reader is gone)."""
    try:
        with os.fdopen(fd, "wb") as pipe:
            pipe.write(_HEADER.pack(len(data)))
            pipe.write(data)
    except BrokenPipeError:
        pass  # the child ended before reading (it failed, or was stopped): result() reports why


def _fresh_std_streams() -> None:
    """Give a forked child its own ``sys.stdout``/``sys.stderr`` objects.

    Another thread of the parent (a progress spinner) may have held a
    stream's internal lock at the moment of the fork; the child's copy of
    that lock would then never be released. New objects on the same file
    descriptors have new locks.
    """
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        try:
            fd = stream.fileno()
        except (AttributeError, ValueError, OSError):
            continue  # not a real file (captured output): nothing to re-open
        setattr(sys, name, open(fd, "w", buffering=1, encoding=stream.encoding, errors=stream.errors, closefd=False))


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
    inbox : bool
        Call ``fn(receive, *args)``: ``receive()`` waits for the object the
        parent passes to :meth:`send` (``None`` when the parent closes the
        work without sending). In a process the object arrives pickled.
    """

    def __init__(
        self, fn: Callable[..., Any], *args: Any, name: str, process: bool = True, inbox: bool = False, nice: int = 0
    ):
        self.name = name
        self.process = bool(process) and can_fork()
        self._nice = int(nice)
        self._done = False
        self._sent = not inbox
        self._value: Any = None
        self._error: BaseException | None = None
        self._pid: int | None = None
        self._out: int | None = None  # child -> parent: the answer
        self._in: int | None = None  # parent -> child: the inbox
        self._queue: queue.Queue | None = None
        self._thread: threading.Thread | None = None
        self._writer: threading.Thread | None = None  # writes what send() gave to a child
        if self.process:
            self._fork(fn, args, inbox)
        else:
            if inbox:
                self._queue = queue.Queue(maxsize=1)
                args = (self._queue.get, *args)
            self._thread = threading.Thread(target=self._run_here, args=(fn, args), name=f"seatkit-{name}")
            self._thread.start()

    # ------------------------------------------------------------------ thread
    def _run_here(self, fn, args) -> None:
        try:
            self._value = fn(*args)
        except BaseException as exc:  # noqa: BLE001 - handed to result()
            self._error = exc

    # ----------------------------------------------------------------- process
    def _fork(self, fn, args, inbox: bool) -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()  # or the child would hold (and never write) a copy of pending output
            except (AttributeError, ValueError, OSError):
                pass
        out_r, out_w = os.pipe()
        in_r, in_w = os.pipe() if inbox else (None, None)
        parent = os.getpid()
        _prctl()
        pid = os.fork()
        if pid == 0:  # the child: compute, answer, leave without running any of the parent's clean-up
            status = 0
            try:
                _die_with_parent(parent)
                os.close(out_r)
                if inbox:
                    os.close(in_w)

                    def receive():
                        data = _read_message(in_r)
                        return pickle.loads(data) if data else None

                    args = (receive, *args)
                _fresh_std_streams()
                if self._nice:
                    try:
                        os.nice(self._nice)  # yield the cores to the build's critical path when they are short
                    except OSError:
                        pass
                try:
                    payload = pickle.dumps((True, fn(*args)), protocol=_PROTOCOL)
                except BaseException as exc:  # noqa: BLE001 - sent to the parent
                    tb = "".join(traceback.format_exception(exc))
                    payload = pickle.dumps((False, _portable_error(exc), tb), protocol=_PROTOCOL)
                with os.fdopen(out_w, "wb") as pipe:
                    pipe.write(_HEADER.pack(len(payload)))
                    pipe.write(payload)
                sys.stdout.flush()
                sys.stderr.flush()
            except BaseException:  # noqa: BLE001 - e.g. the parent went away (broken pipe)
                status = 1
            finally:
                os._exit(status)
        os.close(out_w)
        if inbox:
            os.close(in_r)
        self._pid, self._out, self._in = pid, out_r, in_w

    def _collect(self) -> None:
        """Read the child's answer to the end, then reap it."""
        fd, self._out = self._out, None
        data = _read_message(fd)
        _, status = os.waitpid(self._pid, 0)
        self._pid = None
        if not data:
            how = (
                f"was killed by signal {os.WTERMSIG(status)}"
                if os.WIFSIGNALED(status)
                else f"exited with status {os.waitstatus_to_exitcode(status)}"
            )
            # one clear line, not a traceback: the cause is outside seatkit
            # (out of memory, a signal from the user or the system)
            self._error = SeatkitError(
                f"the {self.name} process {how} before sending its result "
                "(out of memory, or stopped from outside seatkit)"
            )
            return
        answer = pickle.loads(data)
        if answer[0]:
            self._value = answer[1]
        else:
            self._error = answer[1]
            self._error.add_note(f"(raised in the {self.name} process)\n{answer[2]}")

    # ------------------------------------------------------------------ public
    def send(self, obj: Any) -> None:
        """Hand ``obj`` to the work's ``receive()`` (once; only with ``inbox``).

        Does not wait for the work to take it: a child still getting ready
        reads it from the pipe later (a helper thread writes it meanwhile).
        """
        if self._sent:
            msg = f"{self.name}: send() needs inbox=True and works once"
            raise RuntimeError(msg)
        self._sent = True
        if self._queue is not None:
            self._queue.put(obj)
            return
        self._post(pickle.dumps(obj, protocol=_PROTOCOL))

    def _post(self, data: bytes) -> None:
        """Write a message to the child's inbox on a helper thread (the child may not read yet)."""
        fd, self._in = self._in, None
        self._writer = threading.Thread(target=_write_message, args=(fd, data), name=f"seatkit-{self.name}-send")
        self._writer.start()

    def result(self) -> Any:
        """Wait for the work and return its value, or raise its error."""
        if not self._done:
            if self._thread is not None:
                if not self._sent:  # the work waits in receive(): tell it nothing is coming
                    self._sent = True
                    self._queue.put(None)
                self._thread.join()
            else:
                if not self._sent:  # the work waits in receive(): tell it nothing is coming
                    self._sent = True
                    self._post(b"")
                try:
                    self._collect()
                finally:
                    self.close()
            self._done = True
        if self._error is not None:
            raise self._error
        return self._value

    def close(self) -> None:
        """Stop work whose result is not wanted, and reap its process (idempotent).

        A thread cannot be stopped: this waits for it to finish (a thread
        waiting in ``receive()`` gets ``None``), so that no work of a finished
        build goes on in the background.
        """
        if self._thread is not None:
            if not self._sent:
                self._sent = True
                self._queue.put(None)
            self._thread.join()
            return
        for attr in ("_in", "_out"):
            fd = getattr(self, attr)
            if fd is not None:
                os.close(fd)
                setattr(self, attr, None)
        if self._pid is not None:
            try:
                os.kill(self._pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            os.waitpid(self._pid, 0)
            self._pid = None
        if self._writer is not None:  # the child is gone: the write ends (broken pipe) if it had not
            self._writer.join()
            self._writer = None

    def __enter__(self) -> "Background":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
