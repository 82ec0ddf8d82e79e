"""Checkpoints of a long computation, where a caller may stop it (``seatkit serve``: a newer request).

A core module (no seatkit imports), so that any layer's loop can offer a
checkpoint: the surface fit's iterations call :func:`checkpoint`, and
``seatkit serve`` runs a design inside :func:`stoppable` with a check that
raises when a newer request has arrived.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import contextmanager

_stop = threading.local()


@contextmanager
def stoppable(check: Callable[[], None]):
    """Within it, each :func:`checkpoint` in this thread calls ``check``, which raises to stop the computation.

    ``seatkit serve`` stops a design or a baseline this way when a newer
    request arrives: between the stages of a build (``progress``) and
    between the iterations of a long stage (the surface fit's).
    """
    before = getattr(_stop, "check", None)
    _stop.check = check
    try:
        yield
    finally:
        _stop.check = before


def checkpoint() -> None:
    """A point where a long computation may be stopped (:func:`stoppable`); nothing outside one."""
    check = getattr(_stop, "check", None)
    if check is not None:
        check()
