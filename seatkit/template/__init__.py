"""The YAML-driven support-template engine (paper Section 5).

A template is a YAML file (``templates/chair.yaml``) declaring a grid of
quad faces, the body segments each face supports, the fitting steps and
their parameters; :func:`load_template` validates it and returns a
:class:`YamlTemplate`, a :class:`seatkit.interfaces.SupportTemplate`.
See ``docs/templates.md``; a plugin's own steps are written against
:class:`Option`, :class:`FitState`, :class:`Block`, :class:`FaceState` and
:class:`GridMesh` (``docs/plugins.md``, "Writing a template step").
"""

from seatkit.template.clearance import lift_off_bodies
from seatkit.template.engine import YamlTemplate, grid_to_mesh, load_template
from seatkit.template.flat_patch import FLAT_PATCH_DEFAULTS, FlatPatchTemplate, flat_patch_cage
from seatkit.template.grid import Block, FaceState, FitState, GridMesh
from seatkit.template.options import Option
from seatkit.template.schema import PARAMETERS, read_template
from seatkit.template.steps import BUILTIN_STEPS, builtin_steps

__all__ = [
    "YamlTemplate",
    "load_template",
    "read_template",
    "grid_to_mesh",
    # the flat-patch baseline (a SupportTemplate in Python, not YAML)
    "FlatPatchTemplate",
    "flat_patch_cage",
    "FLAT_PATCH_DEFAULTS",
    "lift_off_bodies",
    "PARAMETERS",
    "BUILTIN_STEPS",
    "builtin_steps",
    # the step author's contract (docs/plugins.md, "Writing a template step")
    "Option",
    "FitState",
    "Block",
    "FaceState",
    "GridMesh",
]
