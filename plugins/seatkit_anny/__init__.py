"""The parametric ``anny`` body model (optional: ``pip install torch==2.13.0`` first, then ``pip install 'seatkit[anny]'``).

Registers the BodyModel ``anny``: a MakeHuman-based body (PyPI ``anny``,
Apache-2.0 code, CC0 MakeHuman data) shaped by gender, age, height, weight,
muscle and proportions. Importing this plugin is cheap: torch and anny are
imported only when a body is built, and their absence is reported then, with
the extra to install.
"""

from __future__ import annotations

from seatkit import hookimpl


@hookimpl
def seatkit_register_body_models():
    from seatkit_anny.model import AnnyBodyModel

    return [AnnyBodyModel()]
