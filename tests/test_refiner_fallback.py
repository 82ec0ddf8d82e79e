"""A cage the refiners refuse: the build refines the template's next cage (stages.refine_first_accepted)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from seatkit.errors import SolverError
from seatkit.stages import MAX_REFINED_CAGES, StageTimer, refine_first_accepted, template_cages


class _Cage:
    """A stand-in for a ControlMesh: only ``meta`` is used on the way."""

    def __init__(self, name):
        self.name = name
        self.meta = {}


class _Refiner:
    """Refuses the cages it is told to, passes the others through (marked refined)."""

    def __init__(self, refuse):
        self.refuse = set(refuse)
        self.seen = []

    def refine(self, mesh, bodies, pressures, *, params=None):
        self.seen.append(mesh.name)
        if mesh.name in self.refuse:
            raise SolverError(f"catmull-clark-fit: the surface of cage {mesh.name} reaches 9.0 mm into the body")
        out = _Cage(mesh.name + "+refined")
        out.meta = dict(mesh.meta)
        return out


def _run(names, refuse):
    cages = iter([_Cage(n) for n in names])
    refiner = _Refiner(refuse)
    timer = StageTimer()
    first = next(cages)
    cage, refined = refine_first_accepted(cages, first, [("fake", refiner, {})], [], [], timer)
    return cage, refined, refiner, timer


def test_the_first_cage_the_refiners_accept_is_the_design_and_the_refusals_are_kept():
    cage, refined, refiner, timer = _run(["a", "b", "c"], refuse={"a"})
    assert cage.name == "b" and refined.name == "b+refined"
    assert refiner.seen == ["a", "b"]  # "c" is never fitted
    assert cage.meta["refiner_refusals"] == ["catmull-clark-fit: the surface of cage a reaches 9.0 mm into the body"]
    assert refined.meta["refiner_refusals"] == cage.meta["refiner_refusals"]
    assert "template" in timer.timings and "refine:fake" in timer.timings


def test_an_accepted_first_cage_is_refined_alone_and_unmarked():
    cage, refined, refiner, _ = _run(["a", "b"], refuse=set())
    assert cage.name == "a" and refiner.seen == ["a"] and "refiner_refusals" not in cage.meta


def test_when_every_cage_is_refused_the_first_refusal_is_raised():
    with pytest.raises(SolverError, match="cage a reaches"):
        _run(["a", "b"], refuse={"a", "b"})


def test_at_most_max_refined_cages_are_refined():
    names = [str(i) for i in range(MAX_REFINED_CAGES + 3)]
    refiner = _Refiner(refuse=set(names))
    cages = iter([_Cage(n) for n in names])
    with pytest.raises(SolverError, match="cage 0 reaches"):
        refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [])
    assert refiner.seen == names[:MAX_REFINED_CAGES]


def test_a_template_without_fits_offers_its_one_cage():
    class One:
        def fit(self, bodies, pressures, *, params=None, seed=0):
            return _Cage(f"seed {seed}")

    assert [c.name for c in template_cages(One(), [], [], params={}, seed=3)] == ["seed 3"]


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


@pytest.mark.slow
def test_a_seed_whose_surface_the_fit_refuses_builds_from_the_templates_next_start():
    """default-female armrest-sitting, seed 7: the seed's cage gives a surface 25 mm into the right thigh."""
    from seatkit.pipeline import build

    r = build({"template": "chair", "seed": 7, "bodies": [{"model": "default-female", "pose": "armrest-sitting"}]}, write=False, processes=False)
    refusals = r.initial_mesh.meta["refiner_refusals"]
    assert len(refusals) == 1 and "above the 5.0 mm limit" in refusals[0]
    assert r.initial_mesh.meta["fit_attempts"]["attempt"] > 1
    assert r.control_mesh.meta["catmull-clark-fit"]["final_depth"]["surface_in_body"] <= 0.005
    ours, flat = r.metrics["ours"][0], r.metrics["baseline"][0]
    assert ours["max_penetration_m"] <= 0.005 and ours["max_body_depth_m"] <= 0.005
    for key in ("avg_distance_m", "avg_pressure_pa", "max_pressure_pa"):
        assert ours[key] < flat[key], key


class _Repairable(_Refiner):
    """Refuses as ``_Refiner`` does, each refusal carrying a repair that succeeds for the cages in ``repairs``."""

    def __init__(self, refuse, repairs):
        super().__init__(refuse)
        self.repairs = set(repairs)
        self.repaired = []

    def refine(self, mesh, bodies, pressures, *, params=None):
        from seatkit.refine.ccfit import SurfaceLimitRefusal

        try:
            return super().refine(mesh, bodies, pressures, params=params)
        except SolverError as e:

            def repair(name=mesh.name):
                self.repaired.append(name)
                return _Cage(name + "+pushed") if name in self.repairs else None

            raise SurfaceLimitRefusal(str(e), repair) from None


def test_a_refusal_is_repaired_only_when_every_cage_is_refused():
    # a later cage accepted: no repair runs, the design is that cage as before
    refiner = _Repairable(refuse={"a"}, repairs={"a"})
    cages = iter([_Cage(n) for n in ["a", "b"]])
    cage, refined = refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [])
    assert refined.name == "b+refined" and refiner.repaired == []
    # every cage refused: the repairs in the cages' order, the first that works is the design,
    # and the refiners after the refusing one still run on it
    refiner = _Repairable(refuse={"a", "b", "c"}, repairs={"b", "c"})
    after = _Refiner(refuse=set())
    cages = iter([_Cage(n) for n in ["a", "b", "c"]])
    cage, refined = refine_first_accepted(cages, next(cages), [("fit", refiner, {}), ("after", after, {})], [], [])
    assert refiner.repaired == ["a", "b"]
    assert cage.name == "b" and refined.name == "b+pushed+refined"
    assert refined.meta["repaired_refusal"] == "catmull-clark-fit: the surface of cage b reaches 9.0 mm into the body"
    assert len(refined.meta["refiner_refusals"]) == 3
    # no repair works: the first refusal, as before
    refiner = _Repairable(refuse={"a", "b"}, repairs=set())
    cages = iter([_Cage(n) for n in ["a", "b"]])
    with pytest.raises(SolverError, match="cage a reaches") as refusal:
        refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [])
    assert refiner.repaired == ["a", "b"]
    assert type(refusal.value) is SolverError  # what a build refused before raised


def test_a_repairable_refusal_crosses_a_process_as_a_plain_solver_error():
    import pickle

    from seatkit.refine.ccfit import SurfaceLimitRefusal

    e = pickle.loads(pickle.dumps(SurfaceLimitRefusal("catmull-clark-fit: 9.0 mm", lambda: None)))
    assert type(e) is SolverError and str(e) == "catmull-clark-fit: 9.0 mm"


class _Refused:
    """The surface a refusal keeps (``SurfaceLimitRefusal.closest``): only its control points are used."""

    def __init__(self, name):
        self.vertices = name


class _Closest(_Repairable):
    """Refuses as ``_Repairable`` does, each refusal keeping its refused surface (its control points: the cage's name)."""

    def refine(self, mesh, bodies, pressures, *, params=None):
        from seatkit.refine.ccfit import SurfaceLimitRefusal

        try:
            return super().refine(mesh, bodies, pressures, params=params)
        except SurfaceLimitRefusal as e:
            raise SurfaceLimitRefusal(str(e), e.repair, closest=_Refused(mesh.name)) from None


def test_walls_against_the_refused_surfaces_come_after_every_repair():
    asked = []

    def walls(cage, refused):
        asked.append((cage.name, refused))
        return _Cage(cage.name + "+walls") if cage.name != "a" else None

    # a cage accepted, or a local repair that works: no walls are asked for
    refiner = _Closest(refuse={"a"}, repairs=set())
    cages = iter([_Cage(n) for n in ["a", "b"]])
    assert refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], walls=walls)[1].name == "b+refined"
    refiner = _Closest(refuse={"a", "b"}, repairs={"b"})
    cages = iter([_Cage(n) for n in ["a", "b"]])
    assert refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], walls=walls)[1].name == "b+pushed"
    assert asked == []
    # every cage and every repair refused: each cage's walls against its refused surface, in order, refined by every refiner
    refiner = _Closest(refuse={"a", "b", "c"}, repairs=set())
    after = _Refiner(refuse=set())
    cages = iter([_Cage(n) for n in ["a", "b", "c"]])
    cage, refined = refine_first_accepted(cages, next(cages), [("fit", refiner, {}), ("after", after, {})], [], [], walls=walls)
    assert asked == [("a", "a"), ("b", "b")]
    assert cage.name == "b+walls" and refined.name == "b+walls+refined+refined"
    assert refined.meta["walls_against"] == cage.meta["walls_against"] == "catmull-clark-fit: the surface of cage b reaches 9.0 mm into the body"
    assert len(refined.meta["refiner_refusals"]) == 3
    # the walled cages refused too (and their repairs): the first refusal, as before
    asked.clear()
    refiner = _Closest(refuse={"a", "b", "b+walls"}, repairs=set())
    cages = iter([_Cage(n) for n in ["a", "b"]])
    with pytest.raises(SolverError, match="cage a reaches") as refusal:
        refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], walls=walls)
    assert asked == [("a", "a"), ("b", "b")] and refiner.repaired == ["a", "b", "b+walls"]
    assert type(refusal.value) is SolverError


def test_last_resort_cages_are_asked_for_only_when_every_cage_and_repair_is_refused():
    asked = []

    def last_resort(names):
        def make():
            asked.append(True)
            return iter([_Cage(n) for n in names])

        return make

    # a later cage accepted, or a repair: the last-resort cages are never made, the design is as before
    for refuse, repairs, want in (({"a"}, set(), "b+refined"), ({"a", "b"}, {"a"}, "a+pushed")):
        refiner = _Repairable(refuse=refuse, repairs=repairs)
        cages = iter([_Cage(n) for n in ["a", "b"]])
        cage, refined = refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], last_resort=last_resort(["z"]))
        assert refined.name == want and asked == []
    # every cage and every repair refused: the last-resort cages, in order, then their repairs
    refiner = _Repairable(refuse={"a", "b", "x"}, repairs=set())
    cages = iter([_Cage(n) for n in ["a", "b"]])
    cage, refined = refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], last_resort=last_resort(["x", "y"]))
    assert asked == [True] and refiner.seen == ["a", "b", "x", "y"] and refiner.repaired == ["a", "b"]  # y accepted: no repair of x
    assert cage.name == "y" and refined.name == "y+refined" and len(refined.meta["refiner_refusals"]) == 3
    refiner = _Repairable(refuse={"a", "x", "y"}, repairs={"y"})
    cages = iter([_Cage("a")])
    cage, refined = refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], last_resort=last_resort(["x", "y"]))
    assert refiner.repaired == ["a", "x", "y"] and refined.name == "y+pushed"
    # none accepted, or the template refuses every last-resort start: the first refusal, as before
    from seatkit.errors import UnsupportedPoseError

    def refused_template():
        raise UnsupportedPoseError("the fitted cage crosses the body at faces foot.left")
        yield  # a generator, as YamlTemplate.fits

    for more in (last_resort(["x"]), refused_template, lambda: iter([])):
        refiner = _Repairable(refuse={"a", "x"}, repairs=set())
        cages = iter([_Cage("a")])
        with pytest.raises(SolverError, match="cage a reaches") as refusal:
            refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], last_resort=more)
        assert type(refusal.value) is SolverError


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


def test_the_walls_come_before_the_last_resort_cages():
    """Walls against the refused surface, then the template's last-resort cages: each only when everything before it was refused."""
    order = []

    def walls(cage, refused):
        order.append(("walls", cage.name))
        return _Cage(cage.name + "+walls")

    def last_resort():
        order.append(("last resort", None))
        return iter([_Cage("x")])

    refiner = _Closest(refuse={"a", "a+walls"}, repairs=set())
    cages = iter([_Cage("a")])
    cage, refined = refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], walls=walls, last_resort=last_resort)
    assert order == [("walls", "a"), ("last resort", None)]
    assert cage.name == "x" and refined.name == "x+refined"
    # a walled cage accepted: the last resort is not asked for
    order.clear()
    refiner = _Closest(refuse={"a"}, repairs=set())
    cages = iter([_Cage("a")])
    assert refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], walls=walls, last_resort=last_resort)[1].name == "a+walls+refined"
    assert order == [("walls", "a")]


def test_a_template_that_refuses_its_start_again_offers_no_walls():
    """A plugin's ``walls_against`` may raise UnsupportedPoseError: the build goes on (here to the last resort) and, refused, says the first cage's refusal."""
    from seatkit.errors import UnsupportedPoseError

    def walls(cage, refused):
        raise UnsupportedPoseError(f"the fitted cage crosses the body at faces of {cage.name}")

    refiner = _Closest(refuse={"a", "x"}, repairs=set())
    cages = iter([_Cage("a")])
    with pytest.raises(SolverError, match="cage a reaches") as refusal:
        refine_first_accepted(cages, next(cages), [("fake", refiner, {})], [], [], walls=walls, last_resort=lambda: iter([_Cage("x")]))
    assert type(refusal.value) is SolverError and refiner.seen == ["a", "x"]
