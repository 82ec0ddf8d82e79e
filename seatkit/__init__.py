"""seatkit: design body-supporting furniture from a human body in a pose.

Public API::

    import seatkit
    result = seatkit.build({"template": "chair"})      # one build, a BuildResult
    seatkit.hookimpl                                     # for plugins
    seatkit.jsonable(result.metrics)                     # plain JSON data, as report.json writes it

The data types (:mod:`seatkit.model`) and interfaces (:mod:`seatkit.interfaces`)
are re-exported here; heavy modules are imported on first use so that
``import seatkit`` stays fast.
"""

from __future__ import annotations

import pluggy

from seatkit.errors import SeatkitError
from seatkit.io import jsonable
from seatkit.model import Body, BuildResult, ControlMesh, Pose, PressureField, RiggedBody, Surface

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


def build(recipe, **kwargs):
    """Run one build from a recipe (mapping or path); see :func:`seatkit.pipeline.build`."""
    from seatkit.pipeline import build as _build

    return _build(recipe, **kwargs)
