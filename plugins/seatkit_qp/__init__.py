"""The built-in pressure solver ``qp`` (the paper's Section 4 QP).

Registered through the ``seatkit`` entry point group exactly like a
third-party plugin. Importing this module is cheap; the solver module is
imported when the hook runs.
"""

from __future__ import annotations

from seatkit import hookimpl


@hookimpl
def seatkit_register_pressure_solvers():
    from seatkit.pressure.qp import QPPressureSolver

    return [QPPressureSolver()]
