"""Shared builders for the report tests (no tests here).

One flat-patch build, evaluated by the pipeline against the flat-patch
baseline (``metrics["ours"/"baseline"]``, ``contact_pressures``,
``baseline``), cached for the session; :func:`plain_result` is the
same build with the evaluation stripped (what ``--no-evaluate`` gives).
"""

from __future__ import annotations

import copy
import functools


@functools.lru_cache(maxsize=1)
def _built():
    from seatkit.pipeline import build

    return build({"template": "flat-patch"}, write=False)


def evaluated_result():
    """The flat-patch build with the pipeline's evaluation and baseline."""
    res = copy.copy(_built())
    assert res.metrics.get("ours") and res.metrics.get("baseline"), "the pipeline's evaluation stage did not run"
    assert res.baseline is not None and res.contact_pressures
    return res


def plain_result():
    """The same build without metrics, contact or interface pressure, or baseline."""
    res = copy.copy(_built())
    res.metrics, res.contact_pressures, res.interface_pressures, res.baseline = {}, None, None, None
    return res
