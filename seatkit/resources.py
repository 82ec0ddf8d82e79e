"""Where seatkit's shipped data lives, installed or in a source checkout.

The repository keeps furniture templates in the top-level ``templates/``
folder (the project card asks for it there); the wheel installs them inside
the package as ``seatkit/templates``. :func:`template_path` finds them in
either place, so code never hard-codes one layout.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def templates_dir() -> Path:
    """The folder of shipped template YAML files."""
    installed = _PACKAGE / "templates"
    if installed.is_dir():
        return installed
    return _PACKAGE.parent / "templates"


def template_path(name: str) -> Path:
    """Path of a shipped template file, e.g. ``template_path("chair.yaml")``."""
    return templates_dir() / name


def data_path(*parts: str) -> Path:
    """Path inside ``seatkit/data`` (bodies, poses, name maps)."""
    return _PACKAGE.joinpath("data", *parts)
