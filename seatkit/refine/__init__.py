"""Refiners that improve a cage after the template.

- :class:`OptimizeRefiner` (``optimize``): the paper's mesh optimisation
  (Section 5.3, Appendix B), :func:`optimize_cage`.
- :class:`CatmullClarkFitRefiner` (``catmull-clark-fit``): the Sit & Relax
  limit-surface fit, :func:`fit_cage`.
- :func:`cage_quality`: planarity, angles and regularity of a quad cage.
"""

from seatkit.refine.ccfit import CCFIT_DEFAULTS, CatmullClarkFitRefiner, fit_cage, fit_report, surface_distances
from seatkit.refine.optimize import OPTIMIZE_DEFAULTS, OptimizeRefiner, optimize_cage
from seatkit.refine.quality import cage_quality

__all__ = [
    "CCFIT_DEFAULTS",
    "OPTIMIZE_DEFAULTS",
    "CatmullClarkFitRefiner",
    "OptimizeRefiner",
    "cage_quality",
    "fit_cage",
    "fit_report",
    "optimize_cage",
    "surface_distances",
]
