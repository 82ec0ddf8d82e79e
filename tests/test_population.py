"""Population accommodation (seatkit.population, ``seatkit accommodate``): the sampler, the criteria, a small study on Dask."""

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from seatkit.cli import app


@pytest.mark.parametrize("sex", ["female", "male"])
def test_sampler_marginals_match_the_survey(sex):
    from seatkit.population import load_population, sample_people

    stats = load_population("ansur-ii")
    people, redrawn = sample_people(4000, seed=7, female_share=1.0 if sex == "female" else 0.0)
    assert {p.sex for p in people} == {sex}
    cols = stats["columns"]
    x = np.array([[p.figures[c] for c in cols] for p in people])
    survey = stats["sexes"][sex]
    # the survey's plain means and standard deviations (not the log-normal's parameters the sampler uses)
    np.testing.assert_allclose(x.mean(axis=0), survey["mean"], rtol=0.006)
    np.testing.assert_allclose(x.std(axis=0, ddof=1), survey["sd"], rtol=0.06)
    # log-normal: mass is skewed to the right, as a survey's body mass is (its median below its mean)
    from scipy.stats import skew

    assert skew(x[:, cols.index("mass")]) > 0.3
    # the body model takes almost every draw
    assert redrawn < 0.02 * len(people)
    # and the figures keep the survey's correlation of stature and sitting height
    r = np.corrcoef(np.log(x[:, cols.index("stature")]), np.log(x[:, cols.index("sitting_height")]))[0, 1]
    c = np.asarray(survey["cov_log"])
    i, j = cols.index("stature"), cols.index("sitting_height")
    assert r == pytest.approx(c[i, j] / np.sqrt(c[i, i] * c[j, j]), abs=0.03)


def test_sampler_is_reproducible_and_shares_the_sexes():
    from seatkit.population import sample_people

    a, _ = sample_people(300, seed=3)
    b, _ = sample_people(300, seed=3)
    assert a == b
    assert sample_people(40, seed=3)[0] == a[:40]  # a smaller study is the start of a larger one
    assert sample_people(40, seed=4)[0] != a[:40]
    women = sum(p.sex == "female" for p in a)
    assert 120 <= women <= 180  # half, within sampling error


def test_statistics_file_names_its_source_and_describes_the_survey_the_presets_come_from():
    from seatkit.body.presets import preset_table
    from seatkit.population import load_population

    stats = load_population("ansur-ii")
    assert "ANSUR II" in stats["source"] and "make_population_stats.py" in stats["command"]
    assert len(stats["files_sha256"]) == 2 and all(len(h) == 64 for h in stats["files_sha256"].values())
    presets = preset_table()["presets"]
    for sex in ("female", "male"):
        s = stats["sexes"][sex]
        assert np.all(np.linalg.eigvalsh(np.asarray(s["cov_log"])) > 0)
        assert s["n"] == presets[f"p50-{sex}"]["survey"]["n"]
        # the log-normal's median, exp(mean_log), is the survey's 50th percentile the p50 manikin was made to
        for key, median in zip(stats["columns"], np.exp(s["mean_log"])):
            assert median == pytest.approx(presets[f"p50-{sex}"]["survey"][key], rel=0.015), (sex, key)


def test_person_params_give_the_preset_inputs_at_the_manikins():
    from seatkit.body.presets import preset_table
    from seatkit.population import Person, person_params

    for name, p in preset_table()["presets"].items():
        figures = {**p["survey"]}
        model, params = person_params(Person(0, p["sex"], figures))
        assert model == f"default-{p['sex']}"
        assert params["height"] == p["survey"]["stature"] and params["mass"] == p["survey"]["mass"]
        for key, value in p["model_inputs"].items():
            assert params[key] == pytest.approx(value, abs=1e-4), (name, key)


def test_criteria_name_each_reason():
    from seatkit.population import judge

    ref = {"max_pressure_pa": 8000.0, "max_moment_nm": 30.0}
    good = {"supported": True, "max_penetration_m": 0.001, "max_body_depth_m": 0.002, "max_pressure_pa": 9000.0, "max_moment_nm": 35.0}
    fit = {"seat_height_m": 0.43, "seat_height_for_shoes_m": 0.45, "seat_depth_difference_m": -0.02}
    assert judge(good, fit, ref) == []
    assert judge({"supported": False, "reason": "no contact"}, fit, ref)[0].startswith("not supported")
    bad = judge({**good, "max_body_depth_m": 0.008, "max_pressure_pa": 17000.0}, {**fit, "seat_height_m": 0.47, "seat_depth_difference_m": 0.01}, ref)
    heads = [r.split(":")[0] for r in bad]
    assert heads == ["part cut", "peak pressure too high", "seat too high", "seat too deep"]
    assert judge(good, {**fit, "seat_height_m": 0.35}, ref)[0].startswith("seat too low")


def test_small_study_on_dask_writes_its_table_and_plot_and_resumes(p50_upright_design, tmp_path):
    from PIL import Image

    from seatkit.population import run_accommodation

    out = tmp_path / "study"
    first = run_accommodation(p50_upright_design, out, n=3, seed=1, workers=1)
    assert first["n"] == 3 and first["run"]["run_now"] == 3
    rows = list(csv.DictReader((out / "people.csv").open()))
    assert len(rows) == 3
    for r in rows:
        assert r["accommodated"] in ("True", "False")
        assert (r["accommodated"] == "True") == (r["reason"] == "")
        assert r["supported"] == "True" and float(r["stature"]) > 1.3
    failed = list(csv.DictReader((out / "not-accommodated.csv").open()))
    assert [f["person"] for f in failed] == [r["person"] for r in rows if r["accommodated"] == "False"]
    assert all(f["reason"] for f in failed)
    assert first["accommodated"] == 3 - len(failed)
    with Image.open(out / "accommodation.png") as im:
        pixels = np.asarray(im.convert("RGB")).reshape(-1, 3)
    assert len(np.unique(pixels, axis=0)) > 20
    # interrupted: one person's result lost; the same command runs only that person again
    (out / "people" / "00002-{}.json".format(rows[2]["sex"])).unlink()
    again = run_accommodation(p50_upright_design, out, n=3, seed=1, workers=1)
    assert again["run"]["run_now"] == 1 and again["run"]["already_done"] == 2
    assert again["accommodated"] == first["accommodated"]
    summary = json.loads((out / "accommodation.json").read_text())
    assert summary["share"] == pytest.approx(first["accommodated"] / 3)
    # another build's own figures as the limits (designs compared under one limit): the people are
    # judged again without new trials; a reference far below everyone's figures fails them all on
    # both limits, one far above fails nobody on them
    people = {r["person"]: r for r in csv.DictReader((out / "people.csv").open())}
    for scale, failing in ((1e-6, True), (1e6, False)):
        ref = tmp_path / f"ref{scale:g}"
        ref.mkdir()
        own = [{"supported": True, "max_pressure_pa": 8000.0 * scale, "max_moment_nm": 30.0 * scale}]
        (ref / "report.json").write_text(json.dumps({"metrics": {"ours": own}}))
        judged = run_accommodation(p50_upright_design, out, n=3, seed=1, workers=1, reference=ref)
        assert judged["run"]["run_now"] == 0
        assert judged["reference"]["max_pressure_pa"] == pytest.approx(8000.0 * scale)
        assert str(ref) in judged["criteria"]["peak pressure"]
        rows = list(csv.DictReader((out / "people.csv").open()))
        for r in rows:
            assert float(r["max_pressure_pa"]) == pytest.approx(float(people[r["person"]]["max_pressure_pa"]))
            heads = [x.split(":")[0] for x in r["reason"].split("; ") if x]
            assert (("peak pressure too high" in heads) and ("joint moment too high" in heads)) == failing
            assert failing or not ({"peak pressure too high", "joint moment too high"} & set(heads))
        # the people one criterion alone fails, by that criterion
        single = [r["reason"].split(":")[0] for r in rows if r["reason"] and "; " not in r["reason"]]
        assert judged["sole_reasons"] == {h: single.count(h) for h in set(single)}
        assert not failing or not judged["sole_reasons"]  # both limits fail everyone: nobody has one reason


@pytest.mark.parametrize(
    "args, expected",
    [
        (["accommodate", "/no/such/folder", "--n", "3"], "no such folder"),
        (["accommodate", "{design}", "--n", "0"], "--n: expected a whole number"),
        (["accommodate", "{design}", "--n", "-5"], "--n: expected a whole number"),
        (["accommodate", "{design}", "--population", "mars"], "unknown population"),
        (["accommodate", "{design}", "--female-share", "2"], "--female-share"),
        (["accommodate", "{design}", "--reference", "/no/such/folder"], "/no/such/folder/report.json: expected the build's report.json"),
    ],
)
def test_accommodate_bad_input_gets_one_line(p50_upright_design, tmp_path, args, expected):
    args = [a.format(design=p50_upright_design) for a in args]
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "x")])
    assert res.exit_code != 0
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and expected in lines[0], res.output
    assert not (tmp_path / "x").exists()


def test_design_reference_reads_any_report_json_or_refuses_in_one_line(tmp_path):
    from hypothesis import example, given, settings
    from hypothesis import strategies as st

    from seatkit.errors import InputError
    from seatkit.population import design_reference

    figures = st.fixed_dictionaries({}, optional={
        "supported": st.booleans(),
        "max_pressure_pa": st.one_of(st.floats(allow_nan=True), st.text(max_size=5), st.none()),
        "max_moment_nm": st.one_of(st.floats(allow_nan=True), st.integers(), st.none()),
    })
    documents = st.one_of(
        st.binary(max_size=64).map(lambda b: b.decode("latin-1")),
        st.recursive(st.none() | st.booleans() | st.floats() | st.text(max_size=5), lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=5), c, max_size=3), max_leaves=8).map(json.dumps),
        st.lists(figures, max_size=3).map(lambda ours: json.dumps({"metrics": {"ours": ours}})),
    )

    @settings(max_examples=150, deadline=None)
    @example('{"metrics": {"ours": [{"supported": true, "max_pressure_pa": NaN, "max_moment_nm": 3}]}}')
    @example('{"metrics": {"ours": [{"supported": true, "max_pressure_pa": -1, "max_moment_nm": 3}]}}')
    @example('{"metrics": {"ours": ["x"]}}')
    @example('{"metrics": {"ours": [{"supported": true, "max_pressure_pa": 9000, "max_moment_nm": 30}]}}')
    @given(documents)
    def check(text):
        (tmp_path / "report.json").write_text(text, encoding="utf-8")
        try:
            ref = design_reference(tmp_path)
        except InputError as e:
            assert "\n" not in str(e) and "report.json" in str(e)
            return
        assert set(ref) == {"max_pressure_pa", "max_moment_nm"}
        assert all(np.isfinite(v) and v > 0 for v in ref.values())

    check()


def test_a_person_who_could_not_be_tried_counts_as_one_error_whatever_the_message():
    from seatkit.population import reason_heads

    message = "error: default-male: popliteal_height 0.49 m would move the hip joints +6 cm in the pelvis; accepted up to 6 cm either way"
    assert reason_heads(message) == ["error"]
    assert reason_heads("seat too high: 0.50 m against 0.45 m; part cut: 7 mm") == ["seat too high", "part cut"]
