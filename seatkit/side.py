"""A side thread for the independent pieces of one computation, where a process has the machine to itself.

``seatkit serve`` designs one chair at a time, with nothing else to run on
a two-core machine: the surface fit's correspondences (a k-d tree over the
limit samples, built and queried without holding the GIL) can run beside
its probes' skin distances, and the three parts of its final 5 mm check
beside each other. The values are the same whichever thread computes them:
each piece is a function of its arguments alone.

A command-line build keeps its second core for its baseline's helper
process (:mod:`seatkit.workers`), and a batch runs one build per core, so
the side thread is off unless a program turns it on with
:func:`use_side_thread` (``seatkit serve`` does).
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable

__all__ = ["beside", "side_thread_on", "use_side_thread"]

_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None


def use_side_thread(enabled: bool = True) -> None:
    """Turn the side thread on (one worker thread, started now) or off (it finishes its work first)."""
    global _pool
    with _lock:
        if enabled and _pool is None:
            _pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="seatkit-side")
        elif not enabled and _pool is not None:
            _pool.shutdown(wait=True)
            _pool = None


def side_thread_on() -> bool:
    """Whether :func:`beside` runs work on the side thread."""
    return _pool is not None


def beside(fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Callable[[], Any]:
    """Start ``fn(*args, **kwargs)`` on the side thread; return a function that waits for its value.

    The waiting function re-raises what ``fn`` raised. With the side thread
    off, ``fn`` runs now, in the caller's thread, and the function returns
    its value.
    """
    pool = _pool
    if pool is None:
        value = fn(*args, **kwargs)
        return lambda: value
    return pool.submit(fn, *args, **kwargs).result
