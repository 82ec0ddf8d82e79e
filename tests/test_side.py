"""The side thread (seatkit.side): off by default, the same values whichever thread computes them."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from seatkit.side import beside, side_thread_on, use_side_thread


@pytest.fixture
def side_thread():
    use_side_thread(True)
    try:
        yield
    finally:
        use_side_thread(False)


def _name(*_args):
    return threading.current_thread().name


def _fail():
    raise ValueError("broken")


def test_off_by_default_work_runs_at_once_in_the_callers_thread():
    assert not side_thread_on()
    assert beside(_name)() == threading.current_thread().name
    with pytest.raises(ValueError, match="broken"):
        beside(_fail)


def test_on_work_runs_on_the_side_thread_and_errors_come_back_when_waited_for(side_thread):
    assert side_thread_on()
    assert beside(_name)().startswith("seatkit-side")
    wait = beside(_fail)  # not raised yet
    with pytest.raises(ValueError, match="broken"):
        wait()


def test_the_surface_fit_gives_the_same_cage_with_and_without_the_side_thread(seated):
    from seatkit.refine import fit_cage, optimize_cage
    from seatkit.resources import template_path
    from seatkit.template import load_template

    body, pressure = seated["reclined-sitting"]
    cage = optimize_cage(load_template(template_path("chair.yaml")).fit([body], [pressure], seed=0))
    alone = fit_cage(cage, [body], [pressure])
    use_side_thread(True)
    try:
        side = fit_cage(cage, [body], [pressure])
    finally:
        use_side_thread(False)
    assert np.array_equal(alone.vertices, side.vertices)
    a, b = alone.meta["catmull-clark-fit"], side.meta["catmull-clark-fit"]
    assert a["final_depth"] == b["final_depth"] and a["history"] == b["history"] and a["iterations"] == b["iterations"]
