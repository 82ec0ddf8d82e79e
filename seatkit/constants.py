"""Physical constants, defaults and tolerances, each with its unit.

Every number the pipeline uses as a default lives here, so that a reader can
see at a glance which units the code works in (SI: metres, kilograms,
newtons, pascals, radians) and a recipe or template can override it by name.
"""

from __future__ import annotations

#: Standard gravity, m/s^2 (pointing along -Y, the world's down).
GRAVITY = 9.81

#: Default body mass, kg (735.75 N of weight).
DEFAULT_BODY_MASS = 75.0

#: The paper's moment/pressure balance lambda (Eq. 4), dimensionless in SI
#: units (forces in N, areas in m^2, moments in N m).
DEFAULT_LAMBDA = 0.013

#: A body's largest extent must lie in this range, m, whatever its source
#: (a preset, a .npz rig, glTF, a plugin's model): smaller is a toy or the
#: wrong unit (millimetres read as metres give kilometres), larger is a
#: mistake (a building, a scaled node, garbage).
BODY_SIZE_RANGE = (0.3, 3.0)

#: Coulomb friction coefficient between body and support, dimensionless.
DEFAULT_MU = 0.5

#: Accepted lambda (besides inf, a rigid body) and mu: beyond these the QP is
#: ill-conditioned (lambda 1e308) or meaningless (mu inf); recipes, flags and
#: the solver all refuse them.
LAMBDA_RANGE = (1e-9, 1e6)
MU_RANGE = (0.0, 10.0)

#: World up axis (+Y), body faces +Z.
UP = (0.0, 1.0, 0.0)
FORWARD = (0.0, 0.0, 1.0)

#: Geometric tolerance for "on a plane" / "on the ground" tests, m.
GEOMETRY_TOL = 1e-9

#: Default support distance: a body vertex closer than this to the support
#: surface is taken to be in contact, m.
DEFAULT_SUPPORT_DISTANCE = 0.02

#: Physical tolerances of the pressure solution checked after every solve.
FORCE_TOL_RELATIVE = 1e-6  # relative error of the total reaction vs weight
NORMAL_FORCE_TOL = 1e-9  # N: no normal force below -NORMAL_FORCE_TOL
FRICTION_TOL = 1e-9  # N: friction pyramid slack allowed

#: Soft tissue of the compliant contact model (seatkit.pressure.compliant).
#: Young's modulus, Pa: gluteal subcutaneous fat (26.1 kPa) and muscle
#: (62.2 kPa) in series, in equal parts (Isogai et al. 2022, J Phys Ther Sci
#: 34:777, ultrasound with compression, their lowest loads).
TISSUE_YOUNGS_MODULUS_PA = 1.0 / (0.5 / 26.1e3 + 0.5 / 62.2e3)
#: Poisson ratio of soft tissue (nearly incompressible), dimensionless.
TISSUE_POISSON = 0.49
#: Tissue thickness (distance from the skin to the bone) is clipped to this range, m.
TISSUE_THICKNESS_RANGE_M = (0.01, 0.12)

#: Default random seed of a build (RANSAC sampling).
DEFAULT_SEED = 0

#: Niceness added to the build's helper processes (each worker forked from
#: the build, or the fork server and so every worker it forks,
#: :mod:`seatkit.background`; used by :mod:`seatkit.workers`): on two cores three
#: runnable processes would otherwise slow the build's own stages, which are
#: the critical path; the helpers have slack (the baseline is done before our
#: evaluation needs it, the export worker waits for the design).
BACKGROUND_NICE = 5
