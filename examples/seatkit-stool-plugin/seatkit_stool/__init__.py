"""A third-party seatkit plugin: a 2x3 stool (calves and thighs, no backrest).

Everything a template needs is in ``stool.yaml``; this module only tells
seatkit where it is.
"""

from pathlib import Path

import seatkit
from seatkit.template import load_template


@seatkit.hookimpl
def seatkit_register_templates():
    return [load_template(Path(__file__).with_name("stool.yaml"))]
