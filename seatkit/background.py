"""Imported first by the fork server of :mod:`seatkit.workers`: lowers its priority.

The fork server is the process every helper worker is forked from; a forked
process keeps its parent's niceness. Lowering it here, before the fork
server imports anything else (``workers.PRELOAD``), makes those imports and
every worker run :data:`~seatkit.constants.BACKGROUND_NICE` below the build,
whose own stages are the critical path when two cores are shared. Nothing
else imports this module.
"""

from __future__ import annotations

import os

from seatkit.constants import BACKGROUND_NICE

try:
    os.nice(BACKGROUND_NICE)
except (AttributeError, OSError):  # no nice() (Windows), or not allowed
    pass
