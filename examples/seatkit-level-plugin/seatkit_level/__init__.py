"""A third-party seatkit plugin with a template step written in Python.

``level-rows`` makes rows of the joined grid level from side to side: each
vertex line across the named rows (a row boundary, from the person's right
to their left) gets the mean height of its vertices, so that a seat stays
level even when the person sits a little askew. ``level-stool`` is the
example stool template with the step added after ``join``.

See "Writing a template step" in seatkit's docs/plugins.md: the step
declares its options (``seatkit.template.Option``), its prerequisites and
its stage, and reads and changes the documented fitting state
(``seatkit.template.FitState``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

import seatkit
from seatkit.template import FitState, Option, load_template


class LevelRowsStep:
    """Level the named rows of the joined grid from side to side."""

    name = "level-rows"
    description = "give every vertex line across the named rows the mean height of its vertices (a seat level from side to side)"
    stage = "grid"  # works on state.grid, after the blocks were joined
    requires = ("join",)
    options = {
        "rows": Option("rows", "the rows to level", required=True),
        "max_change": Option("number", "largest height change of one vertex; more is an error", 0.05, "m", 0.0, 0.5),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        from seatkit.errors import UnsupportedPoseError

        names = options["rows"]  # required: checked when the template was bound
        grid = state.grid
        kept = state.blocks[0].rows  # grid rows are the kept template rows, in order
        changed = 0.0
        for name in names:
            r = state.spec.rows.index(name)
            if r not in kept:  # a special case removed it
                continue
            i = kept.index(r)
            for b in (i, i + 1):  # the row's two vertex lines
                y = grid.vertices[b, :, 1]
                mean = float(y.mean())
                changed = max(changed, float(np.abs(y - mean).max()))
                grid.vertices[b, :, 1] = mean
        if changed > options["max_change"]:
            msg = f"step level-rows: levelling rows {names} moves a vertex {changed:.3f} m (max_change {options['max_change']} m)"
            raise UnsupportedPoseError(msg)
        state.meta["level-rows"] = {"rows": list(names), "largest_change_m": changed}


@seatkit.hookimpl
def seatkit_register_template_steps():
    return [LevelRowsStep()]


@seatkit.hookimpl
def seatkit_register_templates():
    return [load_template(Path(__file__).with_name("level-stool.yaml"))]
