"""Pressure on a posed body: the paper's Section 4 equilibrium QP.

- :func:`solve_pressure` / :class:`QPPressureSolver` (registered as ``qp``)
- :func:`contact_from_surface`: contact set from a support surface
- :mod:`~seatkit.pressure.areas`, :mod:`~seatkit.pressure.weights`,
  :mod:`~seatkit.pressure.regions`, :mod:`~seatkit.pressure.assembly`,
  :mod:`~seatkit.pressure.solve`, :mod:`~seatkit.pressure.field`
"""

from seatkit.pressure.contact import contact_from_surface
from seatkit.pressure.qp import QPPressureSolver, solve_pressure

__all__ = ["QPPressureSolver", "solve_pressure", "contact_from_surface"]
