"""Built-in plugin: the multi-person bench template (``templates/bench.yaml``).

The bench is the chair's block once per person, joined by connector columns,
with one border and ground rectangle; the same template engine fits it. It
registers exactly as a third-party template plugin would.
"""

from __future__ import annotations

from seatkit import hookimpl


@hookimpl
def seatkit_register_templates() -> list:
    """The ``bench`` template (2 to 6 people)."""
    from seatkit.resources import template_path
    from seatkit.template import load_template

    return [load_template(template_path("bench.yaml"))]
