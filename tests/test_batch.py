"""Batch builds on a real Dask LocalCluster with two worker processes."""

import csv
import filecmp
from pathlib import Path

import pytest

pytest.importorskip("dask.distributed")

from seatkit.batch import collect_items, item_seed, parse_vary, run_batch, sweep_items  # noqa: E402
from seatkit.errors import RecipeError  # noqa: E402
from seatkit.pipeline import build  # noqa: E402

# The flat-patch template keeps this test quick; the batch path is the same for every template.
TEMPLATE = "flat-patch"
FAST = {"refiners": [], "exporters": ["obj", "surface"], "evaluate": {"enabled": False}}
POSES = ["upright-sitting", "reclined-sitting", "armrest-sitting", "lounger", "standing-leaning-back"]


def _recipe_file(folder: Path, name: str, pose: str) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(
        f"template: {TEMPLATE}\nbodies:\n  - pose: {pose}\nrefiners: []\n"
        "exporters: [obj, surface]\nevaluate: {enabled: false}\n"
    )
    return path


@pytest.fixture(scope="module")
def batch_run(tmp_path_factory):
    src = tmp_path_factory.mktemp("items")
    for i, pose in enumerate(POSES):
        _recipe_file(src, f"{i}-{pose}", pose)
    bad = src / "9-bad.yaml"
    bad.write_text(f"template: {TEMPLATE}\nbodies:\n  - pose: {src / 'missing-pose.yaml'}\n")
    out = tmp_path_factory.mktemp("batch")
    items = collect_items([src], out=out, seed=3)
    first = run_batch(items, out, workers=2)
    first_summary = list(csv.DictReader((out / "summary.csv").open()))
    second = run_batch(collect_items([src], out=out, seed=3), out, workers=2)
    return src, out, items, first, second, first_summary


def test_bad_item_is_reported_and_others_complete(batch_run):
    src, out, items, first, _, rows = batch_run
    assert len(items) == 6
    status = {r.name: r.status for r in first}
    assert status.pop("9-bad") == "failed"
    assert set(status.values()) == {"ok"}
    bad = next(r for r in first if r.name == "9-bad")
    assert "missing-pose.yaml" in bad.error and "\n" not in bad.error
    assert [r["name"] for r in rows] == [it.name for it in items]
    assert {r["status"] for r in rows} == {"ok", "failed"}
    assert (out / "summary.png").stat().st_size > 1000


def test_outputs_match_a_single_build(batch_run, tmp_path):
    _, out, items, _, _, _ = batch_run
    item = items[1]
    single = dict(item.recipe, output=str(tmp_path / "single"))
    build(single)
    for name in ("cage.obj", "surface.stl", "surface.obj"):
        assert filecmp.cmp(out / item.name / name, tmp_path / "single" / name, shallow=False), name


def test_second_run_skips_finished_items(batch_run):
    _, out, _, first, second, _ = batch_run
    again = {r.name: r.status for r in second}
    assert again.pop("9-bad") == "failed"
    assert set(again.values()) == {"skipped"}
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert {r["status"] for r in rows} == {"skipped", "failed"}


def test_item_seeds_depend_only_on_name():
    assert item_seed(3, "a") == item_seed(3, "a") != item_seed(3, "b")
    assert item_seed(3, "a") != item_seed(4, "a")


def test_table_items_and_bad_table(tmp_path):
    table = tmp_path / "people.csv"
    table.write_text("name,pose,body,mass\nsmall,upright-sitting,default-female,55\ntall,lounger,default-male,95\n")
    items = collect_items([table], template=TEMPLATE, out=tmp_path / "o")
    assert [it.name for it in items] == ["small", "tall"]
    assert items[0].recipe["bodies"][0]["model"] == "default-female"
    assert items[1].recipe["bodies"][0]["params"]["mass"] == 95
    broken = tmp_path / "broken.csv"
    broken.write_text("name,pose\nx,\n")
    with pytest.raises(RecipeError, match="missing 'pose'"):
        collect_items([broken], out=tmp_path / "o")


def test_sweep_grid_and_vary_parsing(tmp_path):
    key, values = parse_vary("mass=55:110:5")
    assert key == "mass" and values[0] == 55 and values[-1] == 110 and len(values) == 5
    with pytest.raises(RecipeError, match="NAME=LOW:HIGH:COUNT"):
        parse_vary("mass=55:110")
    items = sweep_items(template=TEMPLATE, pose="upright-sitting", body="default-male", vary={"mass": values}, out=tmp_path)
    assert [it.recipe["bodies"][0]["params"]["mass"] for it in items] == values
    assert len({it.recipe["output"] for it in items}) == 5


def test_the_command_exits_1_when_an_item_failed_and_0_when_none_did(batch_run, tmp_path):
    from typer.testing import CliRunner

    from seatkit.cli import app

    src, out, _, _, _, _ = batch_run
    good = [str(p) for p in sorted(src.glob("[0-4]-*.yaml"))]
    unsupported = tmp_path / "feet.yaml"  # passes the checks, fails in the template fit
    unsupported.write_text("template: chair\nbodies:\n  - pose: feet-tucked\nrefiners: []\nexporters: [obj]\n")
    runner = CliRunner()
    failed = runner.invoke(app, ["batch", *good, str(unsupported), "--out", str(out), "--workers", "1"])
    assert failed.exit_code == 1, failed.output
    assert "failed: feet: " in failed.stderr
    assert "0 built, 5 already complete, 1 failed" in failed.stdout
    clean = runner.invoke(app, ["batch", *good, "--out", str(out), "--workers", "1"])
    assert clean.exit_code == 0, clean.output
    assert "0 built, 5 already complete, 0 failed" in clean.stdout


def test_local_workers_keep_glibcs_dynamic_mmap_threshold():
    """The local cluster's workers run without MALLOC_TRIM_THRESHOLD_ (Dask's nanny would set it).

    With it set, glibc maps and unmaps every array over 128 KiB, and the page
    faults made a third of a trial's CPU system time.
    """
    import os

    from seatkit.batch import dask_client

    with dask_client(workers=1) as client:
        seen = client.submit(os.environ.get, "MALLOC_TRIM_THRESHOLD_", "unset", pure=False).result()
    assert seen == "unset"
