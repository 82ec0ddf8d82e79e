"""What a template step can do beyond ``apply``: the optional capabilities the engine looks for.

Each is a :class:`typing.Protocol` checked with ``isinstance`` when the
engine binds a template's steps, so a step written in a plugin gains a
capability by defining the method (docs/plugins.md). They are re-exported
by :mod:`seatkit.interfaces` with the other interfaces.
"""

from __future__ import annotations

from typing import Any, Mapping, Protocol, Sequence, runtime_checkable

__all__ = ["RepairsFaces", "WallsInsideHands", "HasFallback", "HasLastResort"]


@runtime_checkable
class RepairsFaces(Protocol):
    """A template step that can repair the faces the engine's final check names (the clearance step); True when it changed the grid."""

    def repair(self, state: Any, faces: Sequence[int], *, options: Mapping[str, Any]) -> bool: ...


@runtime_checkable
class WallsInsideHands(Protocol):
    """A template step that can put walls inside enclosed body parts (``enclosed``: vertex indices per person); True when it changed the grid."""

    def repair_enclosure(self, state: Any, enclosed: Sequence, *, options: Mapping[str, Any], every_row: bool = False) -> bool: ...


@runtime_checkable
class HasFallback(Protocol):
    """An optional template step that says what doing without it means when the engine drops it (no-backrest)."""

    def fallback(self, state: Any, *, options: Mapping[str, Any]) -> None: ...


@runtime_checkable
class HasLastResort(Protocol):
    """A template step with a last-resort change: ``has_last_resort(options)`` says whether these options ask for one."""

    def has_last_resort(self, options: Mapping[str, Any]) -> bool: ...
