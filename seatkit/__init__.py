"""seatkit: design body-supporting furniture from a human body in a pose.

Public API::

    import seatkit
    result = seatkit.build({"template": "chair"})      # one build, a BuildResult
    seatkit.hookimpl                                     # for plugins
    seatkit.jsonable(result.metrics)                     # plain JSON data, as report.json writes it

The data types (:mod:`seatkit.model`) and :func:`~seatkit.io.jsonable` are
re-exported here, imported on first use: ``import seatkit`` (and so the
``seatkit`` command's start-up, and every plugin's ``from seatkit import
hookimpl``) imports neither numpy nor the data types until they are asked
for.
"""

from __future__ import annotations

import pluggy

from seatkit.errors import SeatkitError

__version__ = "0.1.0"

#: Marker for plugin hook implementations: ``@seatkit.hookimpl``.
hookimpl = pluggy.HookimplMarker("seatkit")

__all__ = [
    "Body",
    "BuildResult",
    "ControlMesh",
    "Pose",
    "PressureField",
    "RiggedBody",
    "SeatkitError",
    "Surface",
    "__version__",
    "build",
    "hookimpl",
    "jsonable",
]


#: The re-exports of :mod:`seatkit.model` (numpy), imported on first use (:func:`__getattr__`).
_MODEL_NAMES = frozenset({"Body", "BuildResult", "ControlMesh", "Pose", "PressureField", "RiggedBody", "Surface"})


def __getattr__(name: str):
    """``seatkit.jsonable`` and the data types of :mod:`seatkit.model`, imported when first asked for."""
    if name == "jsonable":
        from seatkit.io import jsonable as value
    elif name in _MODEL_NAMES:
        from seatkit import model

        value = getattr(model, name)
    else:
        raise AttributeError(f"module 'seatkit' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


def build(recipe, **kwargs):
    """Run one build from a recipe (mapping or path); see :func:`seatkit.pipeline.build`."""
    from seatkit.pipeline import build as _build

    return _build(recipe, **kwargs)
