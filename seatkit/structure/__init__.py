"""Will it hold? A linear-elastic finite-element model of the designed shell.

The shell (the limit surface thickened away from the body, as the ``shell``
exporter writes it) is meshed with quadratic hexahedra
(:mod:`~seatkit.structure.mesh`), loaded by every person's contact pressure
and friction shear from the evaluation (:mod:`~seatkit.structure.loads`)
and by its own weight, held where it meets the floor and solved with
scikit-fem (:mod:`~seatkit.structure.fem`). :func:`analyse` gives the
figures of ``structure.json``, :func:`size_thickness` the thinnest shell
that keeps a safety factor and a deflection limit. The model, its
assumptions and its limits: docs/structure.md.

This package does not use the plugin manager: it works on a build's result
(or its parts) and is called by the pipeline, the ``structure`` exporter and
``seatkit structure``.
"""

from seatkit.structure.analysis import (
    DEFAULT_MAX_DEFLECTION,
    DEFAULT_SAFETY_FACTOR,
    Analysis,
    StructureError,
    analyse,
    check_thickness,
    size_thickness,
)
from seatkit.structure.materials import MATERIALS, Material, get_material

__all__ = [
    "DEFAULT_MAX_DEFLECTION",
    "DEFAULT_SAFETY_FACTOR",
    "MATERIALS",
    "Analysis",
    "Material",
    "StructureError",
    "analyse",
    "check_thickness",
    "get_material",
    "size_thickness",
]
