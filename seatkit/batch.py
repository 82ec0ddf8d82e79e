"""Many builds at once, fanned out on Dask (``dask.distributed``).

A batch is a list of *items*; each item is one recipe (a normalised recipe
mapping, see :mod:`seatkit.recipe`) with its own output folder and seed.
:func:`run_batch` submits one task per item to a Dask cluster (a
``LocalCluster`` sized to the machine, or an existing scheduler), each task
runs :func:`seatkit.pipeline.build` — a pure function of its recipe — and
writes exactly what ``seatkit build`` writes. A failing item records its
one-line error and does not stop the others. An item whose folder already
holds a complete, valid run (:func:`seatkit.io.is_complete`) is skipped, so
re-running the same command resumes after a crash or Ctrl-C.

Items come from :func:`collect_items`: a folder or list of recipe YAML
files, pose files (YAML or BVH) with a shared template, or a CSV/YAML table
of bodies and poses.
"""

from __future__ import annotations

import copy
import csv
import hashlib
import json
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Sequence

from seatkit.errors import MissingExtraError, RecipeError, SeatkitError
from seatkit.io import is_complete, write_text_atomic
from seatkit.metrics import PAPER_TABLE1
from seatkit.recipe import apply_overrides, default_recipe, load_recipe, looks_like_path

#: The paper's Table 1 quantities in summary.csv (seatkit.metrics).
SUMMARY_METRICS = tuple(m.key for m in PAPER_TABLE1)
#: Seat dimensions in summary.csv (seatkit.dimensions; the mean over the people of an item).
SUMMARY_DIMENSIONS = ("seat_height_m", "seat_depth_m", "seat_width_m", "back_height_m")


@dataclass
class BatchItem:
    """One build of a batch."""

    name: str
    recipe: dict
    source: str = ""


@dataclass
class ItemResult:
    """What happened to one item (one row of summary.csv)."""

    name: str
    status: str  # "ok", "skipped" or "failed"
    seconds: float = 0.0
    error: str = ""
    output: str = ""
    inputs: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)


def item_seed(base_seed: int, name: str) -> int:
    """A per-item seed derived from the batch seed and the item's name.

    It depends on nothing else (not the item's position or the number of
    workers), so each item is reproducible on its own.
    """
    digest = hashlib.sha256(f"{base_seed}:{name}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def _safe_name(text: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "-" for c in text[:100])  # a folder name the OS takes
    return keep.strip("-.") or "item"


#: The columns of a batch table; the most rows one may have.
TABLE_COLUMNS = ("pose", "body", "mass", "template", "name")
MAX_TABLE_ROWS = 10_000
#: A body mass in a table, kg (the recipe's range).
TABLE_MASS_RANGE = (20.0, 300.0)


def _table_rows(path: Path) -> list[tuple[int, dict]]:
    """(line, row) of a CSV or YAML table, each value checked: text, or for ``mass`` a number of kg."""
    from seatkit.messages import quote
    from seatkit.yamlio import load_yaml, read_text

    rows: list[tuple[int, dict]] = []
    if path.suffix.lower() == ".csv":
        import io

        fh = io.StringIO(read_text(path, "CSV table"), newline="")  # UTF-8, named by byte offset if not
        reader = csv.DictReader(fh)
        try:
            for row in reader:
                if len(rows) >= MAX_TABLE_ROWS:
                    raise RecipeError(f"{path}:{reader.line_num}: more than {MAX_TABLE_ROWS:,} rows; split the table")
                rows.append((reader.line_num, {(k or "").strip(): v for k, v in row.items() if k}))
        except csv.Error as e:  # a NUL byte, a field past csv's size limit
            raise RecipeError(f"{path}:{reader.line_num}: not a readable CSV table: {e}") from None
        where = {i: f"{path}:{line}" for i, (line, _) in enumerate(rows)}
    else:
        doc = load_yaml(path, "batch table")
        data = doc.data.get("items") if isinstance(doc.data, dict) else doc.data
        if not isinstance(data, list) or not all(isinstance(r, dict) for r in data):
            raise doc.error(("items",), "expected a list of mappings with keys " + ", ".join(TABLE_COLUMNS))
        if len(data) > MAX_TABLE_ROWS:
            raise doc.error(("items",), f"{len(data):,} rows; a table has at most {MAX_TABLE_ROWS:,}: split it")
        rows = [(doc.line(("items", i)) or 0, r) for i, r in enumerate(data)]
        where = {i: f"{path}:{line}" for i, (line, _) in enumerate(rows)}
    out = []
    for i, (line, row) in enumerate(rows):
        clean = {}
        for key, value in row.items():
            if key not in TABLE_COLUMNS:
                msg = f"{where[i]}: row {i + 1}: unknown column {quote(key)}; expected {', '.join(TABLE_COLUMNS)}"
                raise RecipeError(msg)
            if value is None or (isinstance(value, str) and not value.strip()):
                continue
            if key == "mass":
                clean[key] = _table_mass(value, f"{where[i]}: row {i + 1}: mass")
            elif isinstance(value, str) or (isinstance(value, (int, float)) and not isinstance(value, bool) and key == "name"):
                clean[key] = str(value).strip()
            else:
                msg = f"{where[i]}: row {i + 1}: {key}: expected text, got {quote(value)}"
                raise RecipeError(msg)
        out.append((i, where[i], clean))
    return out


def _table_mass(value, where: str) -> float:
    """A body mass from a table cell: a finite number of kg in :data:`TABLE_MASS_RANGE`."""
    from seatkit.messages import quote

    lo, hi = TABLE_MASS_RANGE
    try:
        mass = float(value) if not isinstance(value, bool) and isinstance(value, (str, int, float)) else math.nan
    except (ValueError, OverflowError):
        mass = math.nan
    if not lo <= mass <= hi:  # NaN fails too
        raise RecipeError(f"{where}: expected a body mass in kg from {lo:g} to {hi:g}, got {quote(value)}")
    return mass


def collect_items(
    sources: Sequence[str | Path],
    *,
    template: str | None = None,
    out: Path,
    seed: int = 0,
    base_recipe: dict | None = None,
) -> list[BatchItem]:
    """Turn the ITEMS arguments of ``seatkit batch`` into build items.

    Parameters
    ----------
    sources : sequence of path
        Recipe files (``*.yaml`` with a ``template`` or ``bodies`` key), pose
        files (pose YAML or ``.bvh``), folders of those, or one CSV/YAML
        table (columns ``pose``, optional ``body``, ``mass``, ``template``,
        ``name``).
    template : str, optional
        Template for pose files and tables (default ``chair``).
    out : Path
        Batch output folder; item ``NAME`` writes ``out/NAME``.
    seed : int
        Batch seed; each item gets :func:`item_seed`.

    Raises
    ------
    RecipeError
        For a missing path or an unreadable table, before anything runs.
    """
    base = copy.deepcopy(base_recipe or default_recipe())
    if template:
        base["template"] = template
    files: list[Path] = []
    for src in sources:
        p = Path(src)
        if p.is_dir():
            files.extend(sorted(q for q in p.iterdir() if q.suffix.lower() in (".yaml", ".yml", ".bvh")))
        elif p.is_file():
            files.append(p)
        else:
            raise RecipeError(f"{p}: no such file or folder")
    items: list[BatchItem] = []
    for f in files:
        if f.suffix.lower() == ".csv" or _is_table(f):
            for i, where, row in _table_rows(f):
                pose = row.get("pose", "")
                if not pose:
                    raise RecipeError(f"{where}: row {i + 1}: missing 'pose'")
                try:
                    name = _safe_name(row.get("name") or f"{i:03d}-{Path(pose).stem}")
                    if looks_like_path(pose) and not Path(pose).is_absolute():
                        pose = str((f.parent / pose).resolve())
                except (OSError, ValueError) as e:  # a NUL byte, a name too long for the OS
                    raise RecipeError(f"{where}: row {i + 1}: pose: not a usable pose name or path ({e})") from None
                body = row.get("body")
                try:
                    r = apply_overrides(
                        base, template=row.get("template"), poses=[pose], bodies=[body] if body else None, mass=row.get("mass")
                    )
                except RecipeError as e:  # a body spec that does not parse: say which row
                    raise RecipeError(f"{where}: row {i + 1}: {e}") from None
                items.append(BatchItem(name, r, where))
        elif _is_recipe(f):
            r, _ = load_recipe(f)
            items.append(BatchItem(_safe_name(f.stem), r, str(f)))
        else:
            r = apply_overrides(base, poses=[str(f.resolve())])
            items.append(BatchItem(_safe_name(f.stem), r, str(f)))
    seen: dict[str, str] = {}
    for it in items:
        if it.name in seen:
            raise RecipeError(f"two batch items are both named {it.name!r}: {seen[it.name]} and {it.source}")
        seen[it.name] = it.source
        it.recipe["output"] = str(Path(out) / it.name)
        it.recipe["seed"] = item_seed(seed, it.name)
    return items


def _is_table(path: Path) -> bool:
    if path.suffix.lower() not in (".yaml", ".yml"):
        return False
    from seatkit.io import MAX_FILE_BYTES, check_user_file

    try:  # a regular file only (a FIFO in the folder must not block), its first bytes
        check_user_file(path, "batch table", max_bytes=MAX_FILE_BYTES["YAML"], error=RecipeError)
        with path.open("rb") as fh:
            head = fh.read(4096)
    except (RecipeError, OSError):
        return False
    return head.decode("utf-8", "replace").lstrip().startswith("items:")


def _is_recipe(path: Path) -> bool:
    if path.suffix.lower() not in (".yaml", ".yml"):
        return False
    from seatkit.errors import SeatkitError
    from seatkit.yamlio import load_yaml

    try:  # the safe loader: a hostile file in the folder must not hang the batch
        data = load_yaml(path).data
    except SeatkitError:
        return False
    return isinstance(data, dict) and ("template" in data or "bodies" in data) and "joints" not in data


def run_item(recipe: dict, disabled: Sequence[str] = ()) -> dict:
    """Run one build (on a worker); never raises for a user error.

    A plugin manager cannot travel to a Dask worker: the worker builds its
    own from the installed plugins, with the same ``disabled`` plugins
    (``--disable-plugin``) as the command, and passes it to the build.

    Returns a plain dict (picklable): status, seconds, error, metrics.
    """
    from seatkit.pipeline import build
    from seatkit.plugins import get_plugin_manager

    start = time.perf_counter()
    try:
        # one build per core already: no helper processes on top
        result = build(recipe, pm=get_plugin_manager(disabled=disabled), overwrite=True, processes=False)
    except SeatkitError as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        return {"status": "failed", "seconds": time.perf_counter() - start, "error": first}
    return {
        "status": "ok",
        "seconds": time.perf_counter() - start,
        "error": "",
        "metrics": result.metrics,
    }


def _inputs(item: BatchItem) -> dict:
    r = item.recipe
    return {
        "template": r["template"],
        "poses": ";".join(str(b["pose"]) for b in r["bodies"]),
        "bodies": ";".join(b["model"] for b in r["bodies"]),
        "mass_kg": ";".join(str(b["params"].get("mass", "")) for b in r["bodies"]),
        "height_m": ";".join(str(b["params"].get("height", "")) for b in r["bodies"]),
        "seed": r["seed"],
    }


def _flat_metrics(metrics: dict) -> dict:
    ours = (metrics or {}).get("ours") or []
    if isinstance(ours, dict):
        ours = [ours]
    out = {}
    for key in SUMMARY_METRICS:
        vals = [m.get(key) for m in ours if isinstance(m, dict) and m.get(key) is not None]
        out[key] = max(vals) if key.startswith("max") and vals else (sum(vals) / len(vals) if vals else "")
    dims = [d for d in (metrics or {}).get("dimensions") or [] if isinstance(d, dict)]
    for key in SUMMARY_DIMENSIONS:
        vals = [d[key] for d in dims if d.get(key) is not None]
        out[key] = sum(vals) / len(vals) if vals else ""
    return out


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None):
    """A Dask client: of the scheduler at ``scheduler`` (``tcp://host:8786``), else of a ``LocalCluster``.

    The local cluster has ``workers`` processes (default one per core) of one
    thread each; it is closed with the client.
    """
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as e:  # pragma: no cover - depends on the install
        raise MissingExtraError("dask[distributed]", "batch") from e
    import os

    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        n = workers or os.cpu_count() or 1
        import dask

        # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers; setting it
        # turns off glibc's dynamic mmap threshold, so every numpy array
        # over 128 KiB is mapped and unmapped again, and the page faults
        # took a third of a trial's CPU (system time). Left unset here.
        with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_batch(
    items: Sequence[BatchItem],
    out: Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int, ItemResult], None] | None = None,
    disabled: Sequence[str] = (),
) -> list[ItemResult]:
    """Run every item on Dask; write ``out/summary.csv`` and ``out/summary.png``.

    Parameters
    ----------
    items : sequence of BatchItem
    out : Path
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``); default a
        ``LocalCluster`` with ``workers`` processes (default: one per core).
    workers : int, optional
    progress : callable, optional
        Called as ``progress(done, total, item_result)`` after each item.
    disabled : sequence of str
        Plugins the workers' plugin managers block (see :func:`run_item`).

    Returns
    -------
    list of ItemResult, in item order.
    """
    try:
        from dask.distributed import as_completed
    except ImportError as e:  # pragma: no cover - depends on the install
        raise MissingExtraError("dask[distributed]", "batch") from e

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, ItemResult] = {}
    todo: list[BatchItem] = []
    for it in items:
        if is_complete(Path(it.recipe["output"])):
            prev = _previous_metrics(Path(it.recipe["output"]))
            results[it.name] = ItemResult(it.name, "skipped", output=it.recipe["output"], inputs=_inputs(it), metrics=prev)
        else:
            todo.append(it)
    done = len(results)
    if progress:
        for r in list(results.values()):
            progress(done, len(items), r)
    if todo:
        with dask_client(scheduler, workers) as client:
            futures = {client.submit(run_item, it.recipe, tuple(disabled), key=f"seatkit-{it.name}-{it.recipe['seed']}", pure=False): it for it in todo}
            for fut in as_completed(futures):
                it = futures[fut]
                try:
                    data = fut.result()
                except Exception as e:  # a crash of the worker itself
                    data = {"status": "failed", "seconds": 0.0, "error": f"{type(e).__name__}: {e}".splitlines()[0]}
                res = ItemResult(
                    it.name,
                    data["status"],
                    data.get("seconds", 0.0),
                    data.get("error", ""),
                    it.recipe["output"],
                    _inputs(it),
                    data.get("metrics", {}),
                )
                results[it.name] = res
                done += 1
                if progress:
                    progress(done, len(items), res)
    ordered = [results[it.name] for it in items]
    write_summary(ordered, out)
    return ordered


def _previous_metrics(folder: Path) -> dict:
    try:
        return json.loads((folder / "report.json").read_text()).get("metrics", {})
    except (OSError, ValueError):
        return {}


def write_summary(results: Iterable[ItemResult], out: Path) -> None:
    """``summary.csv`` (one row per item) and ``summary.png`` (metrics across items)."""
    results = list(results)
    cols = ["name", "status", "seconds", "error", "output", "template", "poses", "bodies", "mass_kg", "height_m", "seed", *SUMMARY_METRICS, *SUMMARY_DIMENSIONS]
    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols)
    w.writeheader()
    for r in results:
        row = {"name": r.name, "status": r.status, "seconds": f"{r.seconds:.3f}", "error": r.error, "output": r.output}
        row.update(r.inputs)
        row.update(_flat_metrics(r.metrics))
        w.writerow(row)
    write_text_atomic(Path(out) / "summary.csv", buf.getvalue())
    _summary_plot(results, Path(out) / "summary.png")


def _summary_plot(results: list[ItemResult], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from seatkit.io import atomic_path

    ok = [r for r in results if r.status in ("ok", "skipped")]
    fig, axes = plt.subplots(1, len(SUMMARY_METRICS), figsize=(3.2 * len(SUMMARY_METRICS), 3.2))
    names = [r.name for r in ok]
    for ax, key in zip(axes, SUMMARY_METRICS):
        vals = [_flat_metrics(r.metrics).get(key) for r in ok]
        vals = [v if isinstance(v, (int, float)) else float("nan") for v in vals]
        ax.bar(range(len(vals)), vals, color="#4477aa")
        ax.set_title(key, fontsize=9)
        ax.set_xticks(range(len(vals)))
        ax.set_xticklabels(names, rotation=70, fontsize=6)
    failed = [r.name for r in results if r.status == "failed"]
    fig.suptitle(f"{len(ok)} built, {len(failed)} failed" + (f": {', '.join(failed)}" if failed else ""), fontsize=10)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def sweep_items(
    *,
    template: str,
    pose: str,
    body: str,
    vary: dict[str, Sequence[float]],
    out: Path,
    seed: int = 0,
) -> list[BatchItem]:
    """A population grid: every combination of the ``vary`` values.

    ``vary`` maps a body-model parameter (``height``, ``weight``, ``mass``
    ...) to its values; for the default bodies ``mass`` is the one that
    varies.
    """
    import itertools

    keys = sorted(vary)
    items = []
    for combo in itertools.product(*(vary[k] for k in keys)):
        params = ",".join(f"{k}={v:g}" for k, v in zip(keys, combo))
        name = _safe_name("-".join(f"{k}{v:g}" for k, v in zip(keys, combo)))
        r = apply_overrides(default_recipe(), template=template, poses=[pose], bodies=[body])
        for b in r["bodies"]:
            b["params"].update({k: float(v) for k, v in zip(keys, combo)})
        items.append(BatchItem(name, r, f"sweep:{params}"))
    for it in items:
        it.recipe["output"] = str(Path(out) / it.name)
        it.recipe["seed"] = item_seed(seed, it.name)
    return items


def parse_vary(spec: str) -> tuple[str, list[float]]:
    """``height=1.50:1.95:10`` -> ("height", 10 values from 1.50 to 1.95)."""
    import numpy as np

    key, eq, rng = spec.partition("=")
    parts = rng.split(":")
    try:
        if not eq or len(parts) != 3:
            raise ValueError
        lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
        if n < 1:
            raise ValueError
    except ValueError:
        raise RecipeError(f"--vary {spec!r}: expected NAME=LOW:HIGH:COUNT, e.g. height=1.50:1.95:10") from None
    return key.strip(), [float(x) for x in np.linspace(lo, hi, n)]

