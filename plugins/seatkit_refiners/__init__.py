"""Built-in refiners and the flat-patch baseline template.

Registers the refiners ``optimize`` (the paper's Section 5.3 mesh
optimisation) and ``catmull-clark-fit`` (the Sit & Relax limit-surface fit),
and the template ``flat-patch`` (a flat grid under the body, the baseline
every design is compared with). It uses the same hooks a third-party plugin
would.
"""

from __future__ import annotations

from seatkit import hookimpl


@hookimpl
def seatkit_register_refiners() -> list:
    """The ``optimize`` and ``catmull-clark-fit`` refiners."""
    from seatkit.refine import CatmullClarkFitRefiner, OptimizeRefiner

    return [OptimizeRefiner(), CatmullClarkFitRefiner()]


@hookimpl
def seatkit_register_templates() -> list:
    """The ``flat-patch`` baseline template."""
    from seatkit.template.flat_patch import FlatPatchTemplate

    return [FlatPatchTemplate()]
