"""Built-in plugin: the 3x7 chair and the saddle stool templates and the built-in template steps.

It registers exactly as a third-party plugin would: a template is a YAML
file wrapped by :func:`seatkit.template.load_template`, steps are objects
with ``name``, ``description`` and ``run``.
"""

from __future__ import annotations

from seatkit import hookimpl


@hookimpl
def seatkit_register_templates() -> list:
    """The ``chair`` and ``saddle`` templates (``templates/chair.yaml``, ``templates/saddle.yaml``)."""
    from seatkit.resources import template_path
    from seatkit.template import load_template

    return [load_template(template_path("chair.yaml")), load_template(template_path("saddle.yaml"))]


@hookimpl
def seatkit_register_template_steps() -> list:
    """The built-in fitting steps (fit-planes, bridge, corners, outer-columns, ...)."""
    from seatkit.template import builtin_steps

    return builtin_steps()
