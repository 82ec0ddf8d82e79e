"""The design search (seatkit.search): candidates from declared sources, a verdict for each, the first accepted is the design."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from seatkit.errors import SolverError, UnsupportedPoseError
from seatkit.search import BUDGETS, Origin, bind, judge, search, template_cages


@dataclasses.dataclass(frozen=True)
class _Cage:
    """A stand-in for a ControlMesh: a name, ``meta``, its depth in mm (for the fake fit) and ``vertices`` (its name's letters: two names, two cages)."""

    name: str
    depth_mm: float = 9.0
    meta: dict = dataclasses.field(default_factory=dict)
    faces = np.zeros((1, 4), dtype=np.int64)

    @property
    def vertices(self):
        return np.array([[self.depth_mm] * 3, [float(ord(c)) for c in self.name.ljust(3)[:3]], [float(len(self.name)), 0.0, 0.0]])


def _fitted(cage, depth_mm, limit=0.005):
    """``cage`` as the surface fit leaves it: its report with the two depths."""
    report = {"params": {"surface_limit": limit, "level": 3}, "final_depth": {"surface_in_body": depth_mm / 1000, "body_in_surface": 0.0}, "after": {"mean_distance": 0.02}}
    return dataclasses.replace(cage, name=cage.name + "+fit", meta={**cage.meta, "catmull-clark-fit": report})


class _Fit:
    """The fake refiner: each cage's surface ends ``depth_mm`` deep; a name in ``fail`` is a SolverError."""

    def __init__(self, fail=()):
        self.fail = set(fail)
        self.seen = []

    def __call__(self, cage):
        self.seen.append(cage.name)
        if cage.name in self.fail:
            raise SolverError(f"catmull-clark-fit: the fit of cage {cage.name} diverged")
        return _fitted(cage, cage.depth_mm)


class _Template:
    """A template offering the starts ``starts`` ((name, depth mm)), and optionally walls and last-resort cages."""

    def __init__(self, starts, walls=None, last=None, walled=None):
        self.starts = starts
        self.walled = walled  # (name, depth mm): the first cage encloses a hand, and this is it with walls inside (None: it encloses none)
        if walls is not None:
            self.walls_against = lambda bodies, pressures, cage, refused, *, params=None, seed=0: walls(cage)
        if last is not None:
            self.last_resort_fits = lambda bodies, pressures, *, params=None, seed=0: iter(last())

    def fit(self, bodies, pressures, *, params=None, seed=0):
        return next(self.fits(bodies, pressures))

    def fits(self, bodies, pressures, *, params=None, seed=0):
        for i, (name, depth) in enumerate(self.starts, 1):
            walled_next = self.walled is not None and self.walled[0] is not None
            yield _Cage(name, depth, {"fit_attempts": {"attempt": i, **({"encloses_hands": self.walled is not None, "walled_next": walled_next} if i == 1 else {})}})
            if i == 1 and self.walled is not None and self.walled[0] is not None:
                yield _Cage(self.walled[0], self.walled[1], {"fit_attempts": {"attempt": 1, "walls_inside": True}})


@pytest.fixture(autouse=True)
def _no_push_out(monkeypatch):
    """The fake cages have no surface to push out: the repair offers nothing unless a test says otherwise."""
    monkeypatch.setattr("seatkit.refine.ccfit.push_out", lambda mesh, bodies: None)


def _search(template, fit):
    sources = bind(template, [], [], params={}, seed=0, first=template_cages(template, [], [], params={}, seed=0))
    return search(sources, fit, [])


def test_the_first_accepted_start_is_the_design_and_the_report_names_it_and_every_rejection():
    fit = _Fit()
    outcome = _search(_Template([("a", 9.0), ("b", 2.0), ("c", 1.0)]), fit)
    cage, refined = outcome.design()
    assert cage.name == "b" and refined.name == "b+fit" and fit.seen == ["a", "b"]  # "c" is never fitted
    report = refined.meta["search"]
    assert report == cage.meta["search"]
    assert report["winner"] == {"origin": "start", "start": 2, "candidate": 2}
    rejected, won = report["candidates"]
    assert not rejected["accepted"] and "9.0 mm into the body" in rejected["reason"] and "5.0 mm limit" in rejected["reason"]
    assert won["accepted"] and won["depth_m"] == pytest.approx(0.002)


def test_an_accepted_first_cage_is_refined_alone():
    fit = _Fit()
    cage, _ = _search(_Template([("a", 1.0), ("b", 1.0)]), fit).design()
    assert cage.name == "a" and fit.seen == ["a"] and len(cage.meta["search"]["candidates"]) == 1


def test_a_refiners_solver_error_is_a_rejection_with_its_message():
    fit = _Fit(fail={"a"})
    cage, _ = _search(_Template([("a", 1.0), ("b", 1.0)]), fit).design()
    assert cage.name == "b" and "cage a diverged" in cage.meta["search"]["candidates"][0]["reason"]


def test_each_source_refines_at_most_its_budget_and_a_refused_search_says_why_in_one_line():
    names = [(str(i), 9.0) for i in range(BUDGETS[Origin.START] + 3)]
    fit = _Fit()
    outcome = _search(_Template(names), fit)
    assert fit.seen == [n for n, _ in names[: BUDGETS[Origin.START]]]
    with pytest.raises(SolverError) as refused:
        outcome.design()
    message = str(refused.value)
    assert "\n" not in message and "9.0 mm into the body" in message and "the first cage" in message
    assert outcome.winner is None and all(not t.verdict.accepted for t in outcome.tried)


def test_the_sources_take_turns_in_their_declared_order():
    """Each round asks every source for one candidate: a start, a rejected design pushed out, the first cage with walls inside its hands, walls against a rejected start, a last-resort cage."""
    assert list(BUDGETS) == [Origin.START, Origin.PUSHED_OUT, Origin.WALLS_INSIDE, Origin.WALLS_AGAINST, Origin.LAST_RESORT]
    asked = []

    def walls(cage):
        asked.append("walls " + cage.name)
        return _Cage(cage.name + "+walls", 9.0)

    def last():
        asked.append("last")
        return [_Cage("z", 9.0, {"fit_attempts": {"attempt": 1}}), _Cage("y", 1.0, {"fit_attempts": {"attempt": 2}})]

    fit = _Fit()
    outcome = _search(_Template([("a", 9.0), ("b", 9.0)], walls=walls, last=last), fit)
    cage, refined = outcome.design()
    # the fake cages are not pushed out (the fixture): that source offers nothing
    S, W, L = Origin.START, Origin.WALLS_AGAINST, Origin.LAST_RESORT
    assert [t.candidate.origin for t in outcome.tried] == [S, W, L, S, W, L]
    assert fit.seen == ["a", "a+walls", "z", "b", "b+walls", "y"]
    assert asked == ["walls a", "last", "walls b"]  # walls answer the template's starts only
    assert cage.name == "y" and refined.meta["search"]["winner"] == {"origin": "last-resort", "start": 2, "candidate": 6}


def test_a_first_cage_enclosing_a_hand_is_refined_after_its_walled_cage():
    """The template's first cage with walls inside the hands it encloses is the first candidate; an accepted one is the design, the first cage is never refined."""
    fit = _Fit()
    last = lambda: [_Cage("z", 1.0, {"fit_attempts": {"attempt": 1}})]  # noqa: E731
    outcome = _search(_Template([("a", 1.0), ("b", 1.0)], walls=lambda cage: _Cage(cage.name + "+walls", 1.0), last=last, walled=("a|", 2.0)), fit)
    cage, refined = outcome.design()
    assert fit.seen == ["a|"] and cage.name == "a|"
    assert refined.meta["search"]["winner"] == {"origin": "walls-inside", "start": 1, "candidate": 1}


def test_a_rejected_walled_cage_is_followed_by_its_first_cage_before_walls_against_it_and_last_resort_cages():
    """The first cage comes in the first round, after the walled cage's push-out, before walls against it and the last-resort cages."""
    fit = _Fit()
    last = lambda: [_Cage("z", 1.0, {"fit_attempts": {"attempt": 1}})]  # noqa: E731
    outcome = _search(_Template([("a", 2.0), ("b", 1.0)], walls=lambda cage: _Cage(cage.name + "+walls", 1.0), last=last, walled=("a|", 9.0)), fit)
    cage, refined = outcome.design()
    assert fit.seen == ["a|", "a"] and cage.name == "a"
    assert refined.meta["search"]["winner"] == {"origin": "start", "start": 1, "candidate": 2}


def test_when_walls_do_not_help_the_next_start_is_kept_for_its_turn():
    """A first cage that encloses a hand but whose walls give no better cage: the template's next cage is the next start, refined in the start source's turn, once."""
    fit = _Fit()
    outcome = _search(_Template([("a", 9.0), ("b", 9.0), ("c", 1.0)], last=lambda: [_Cage("z", 9.0, {"fit_attempts": {"attempt": 1}})], walled=(None, 0.0)), fit)
    cage, _ = outcome.design()
    assert fit.seen == ["a", "z", "b", "c"] and cage.name == "c"
    assert [t.candidate.origin for t in outcome.tried] == [Origin.START, Origin.LAST_RESORT, Origin.START, Origin.START]


def test_a_push_out_answers_each_rejected_design_before_the_next_source(monkeypatch):
    """The walled cage's push-out fails, the first cage is rejected and pushed out within the limit: the design, before any last-resort cage."""
    pushed = []

    def push_out(mesh, bodies):
        pushed.append(mesh.name)
        return _fitted(dataclasses.replace(mesh, name=mesh.name + "+pushed"), 4.0) if mesh.name == "a+fit" else None

    monkeypatch.setattr("seatkit.refine.ccfit.push_out", push_out)
    fit = _Fit()
    last = lambda: [_Cage("z", 1.0, {"fit_attempts": {"attempt": 1}})]  # noqa: E731
    outcome = _search(_Template([("a", 7.0), ("b", 1.0)], last=last, walled=("a|", 9.0)), fit)
    cage, refined = outcome.design()
    assert pushed == ["a|+fit", "a+fit"] and fit.seen == ["a|", "a"]
    assert refined.name == "a+fit+pushed+fit" and refined.meta["search"]["winner"] == {"origin": "pushed-out", "start": 1, "candidate": 3}


def test_a_cage_two_sources_derive_alike_is_refined_once():
    """Walls against two rejected starts can be one cage: the second is not refined again, and not counted against the budget."""
    fit = _Fit()
    outcome = _search(_Template([("a", 9.0), ("b", 9.0), ("c", 1.0)], walls=lambda cage: _Cage("w", 9.0)), fit)
    cage, _ = outcome.design()
    assert fit.seen == ["a", "w", "b", "c"] and cage.name == "c"
    assert [t.candidate.origin for t in outcome.tried] == [Origin.START, Origin.WALLS_AGAINST, Origin.START, Origin.START]


def test_each_rejected_design_is_pushed_out_once_and_one_within_the_limit_is_the_design(monkeypatch):
    pushed = []

    def push_out(mesh, bodies):
        pushed.append(mesh.name)
        return _fitted(dataclasses.replace(mesh, name=mesh.name + "+pushed"), 4.0) if mesh.name == "b+fit" else None

    monkeypatch.setattr("seatkit.refine.ccfit.push_out", push_out)
    fit = _Fit()
    outcome = _search(_Template([("a", 12.0), ("b", 6.0), ("c", 8.0)]), fit)
    cage, refined = outcome.design()
    assert pushed == ["a+fit", "b+fit"] and fit.seen == ["a", "b"]  # a's repair fails; b's is within the limit
    assert refined.name == "b+fit+pushed+fit" and cage.name == "b"  # the design, and the template's cage it came from
    assert refined.meta["search"]["winner"] == {"origin": "pushed-out", "start": 2, "candidate": 3}


def test_a_template_without_walls_or_last_resort_offers_only_its_starts_and_one_without_fits_its_one_cage():
    class One:
        def fit(self, bodies, pressures, *, params=None, seed=0):
            return _Cage(f"seed {seed}", 1.0)

    assert [c.name for c in template_cages(One(), [], [], params={}, seed=3)] == ["seed 3"]
    fit = _Fit()
    outcome = _search(_Template([("a", 9.0)]), fit)
    assert [t.candidate.origin for t in outcome.tried] == [Origin.START] and outcome.winner is None


def test_walls_refused_by_the_template_offer_nothing_and_the_search_goes_on():
    def walls(cage):
        raise UnsupportedPoseError("the start is refused again")

    outcome = _search(_Template([("a", 9.0)], walls=walls, last=lambda: [_Cage("z", 1.0)]), _Fit())
    assert outcome.design()[0].name == "z"


def test_the_acceptance_check_reads_the_fits_depths_and_its_limit():
    cage = _Cage("a")
    assert judge(_fitted(cage, 4.9), [], measured=True).accepted
    verdict = judge(_fitted(cage, 5.1), [], measured=True)
    assert not verdict.accepted and "5.1 mm into the body" in verdict.reason and verdict.depth_m == pytest.approx(0.0051)
    assert judge(_fitted(cage, 50.0, limit=0.0), [], measured=True).accepted  # surface_limit 0: off
    assert judge(cage, []).accepted  # no surface fit: nothing to judge


def test_the_report_gives_each_over_limit_fit_of_a_candidate():
    """A candidate whose first fit and refit were over the limit reports both depths, in order; the accepted one none."""

    def fit(cage):
        out = _fitted(cage, cage.depth_mm)
        if cage.name == "a":
            out.meta["catmull-clark-fit"]["repair_rounds"] = [{"surface_in_body": 0.012, "body_in_surface": 0.03}, {"surface_in_body": 0.009, "body_in_surface": 0.004}]
        return out

    _, refined = _search(_Template([("a", 9.0), ("b", 1.0)]), fit).design()
    rows = refined.meta["search"]["candidates"]
    assert rows[0]["over_limit_fits_m"] == [0.03, 0.009] and rows[1]["over_limit_fits_m"] == []


def test_the_chair_offers_its_valid_starts_in_order_and_its_first_is_fit(seated):
    from seatkit.resources import template_path
    from seatkit.template import load_template

    chair = load_template(template_path("chair.yaml"))
    body, pressure = seated["upright-sitting"]
    fits = chair.fits([body], [pressure], seed=0)
    first, second = next(fits), next(fits)
    assert np.array_equal(first.vertices, chair.fit([body], [pressure], seed=0).vertices)
    assert first.meta["fit_attempts"]["attempt"] < second.meta["fit_attempts"]["attempt"]
    assert not np.array_equal(first.vertices, second.vertices)
    assert "first_refusal" not in second.meta["fit_attempts"]  # the first start was valid: nothing refused it


def test_the_chairs_last_resort_cages_put_the_feet_on_the_shanks_planes_and_change_no_other_cage(seated):
    """``fit-planes``' ``last_resort_rows: [foot]``: only the cages of ``last_resort_fits`` change, and there each foot face lies in its shank face's plane."""
    from seatkit.resources import template_path
    from seatkit.template import load_template

    text = template_path("chair.yaml").read_text()
    chair = load_template(text=text, source="chair.yaml")
    without = load_template(text=text.replace("    last_resort_rows: [foot]\n", ""), source="chair.yaml")
    assert "last_resort_rows" in text and "last_resort_rows" not in without.spec.steps[1]
    body, pressure = seated["upright-sitting"]
    first = chair.fit([body], [pressure], seed=0)
    plain = without.fit([body], [pressure], seed=0)
    np.testing.assert_array_equal(first.vertices, plain.vertices)
    assert first.meta == plain.meta
    assert list(without.last_resort_fits([body], [pressure], seed=0)) == []
    offered = list(itertools.islice(chair.last_resort_fits([body], [pressure], seed=0), 3))
    last = offered[0]
    assert last.meta["fit_attempts"]["last_resort"] is True
    assert last.meta["fit_attempts"]["stream"] == "seed" and not last.meta["fit_attempts"]["optional_steps_dropped"]
    # each stream without its optional steps, dropped in turn, before the next stream; no cage offered twice
    assert [m.meta["fit_attempts"]["attempt"] for m in offered] == sorted(m.meta["fit_attempts"]["attempt"] for m in offered)
    assert offered[1].meta["fit_attempts"]["stream"] == "seed" and offered[1].meta["fit_attempts"]["optional_steps_dropped"]
    assert not any(np.array_equal(a.vertices, b.vertices) for a, b in itertools.combinations(offered, 2))
    labels = list(last.face_labels)
    for side in ("right", "left"):
        foot, shank = labels.index(f"foot.{side}"), labels.index(f"shank.{side}")
        np.testing.assert_allclose(last.plane_normals[foot], last.plane_normals[shank])
        np.testing.assert_allclose((last.plane_points[foot] - last.plane_points[shank]) @ last.plane_normals[shank], 0.0, atol=1e-12)
        # ... while the seed's own cage fits the foot its own plane
        assert not np.allclose(first.plane_normals[labels.index(f"foot.{side}")], first.plane_normals[labels.index(f"shank.{side}")])
    record = [c for c in last.meta["special_cases"] if c["case"] == "last-resort-planes"]
    assert record and record[0]["faces"] == ["foot.right", "foot.left"]
    assert not any(c["case"] == "last-resort-planes" for c in first.meta["special_cases"])


@pytest.mark.slow
def test_a_seed_whose_first_surface_is_too_deep_still_gets_a_supporting_chair():
    """default-female armrest-sitting, seed 7: the seed's cage gives a surface 25 mm into the right thigh; the build still finishes within 5 mm, ahead of the flat patch."""
    from seatkit.pipeline import build

    r = build({"template": "chair", "seed": 7, "bodies": [{"model": "default-female", "pose": "armrest-sitting"}]}, write=False, processes=False)
    report = r.control_mesh.meta["search"]
    assert report["winner"] is not None and not report["candidates"][0]["accepted"]
    assert "above the 5.0 mm limit" in report["candidates"][0]["reason"]
    ours, flat = r.metrics["ours"][0], r.metrics["baseline"][0]
    assert ours["max_penetration_m"] <= 0.005 and ours["max_body_depth_m"] <= 0.005
    for key in ("avg_distance_m", "avg_pressure_pa", "max_pressure_pa"):
        assert ours[key] < flat[key], key
