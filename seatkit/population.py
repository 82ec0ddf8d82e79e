"""Population accommodation: what share of a survey's people a design holds.

``seatkit accommodate DESIGN_DIR --population ansur-ii --n N`` samples N
people, builds each one's body, seats each on the design
(:mod:`seatkit.trial`) on Dask, and judges each against the criteria below.

Sampling (:func:`sample_people`)
--------------------------------
``seatkit/data/population/ansur-ii.json`` (``tools/make_population_stats.py``
derives it from the ANSUR II public CSVs, which are not shipped) holds per
sex the mean and covariance of the natural logarithms of stature, mass,
sitting height, hip breadth (sitting), buttock-knee length, popliteal height
and buttock-popliteal length. A person is drawn from that multivariate
**log-normal** (``exp`` of a multivariate normal: every figure positive, mass
skewed to the right as the survey's is), by
:func:`numpy.random.default_rng` seeded with the seed and the person's number
(so the first people of a larger study are those of a smaller one); the sex
is drawn first with
``female_share`` (default one half: a public seat serves women and men
alike, where the survey's own sample is two thirds men). A draw the
parametric body cannot be made to (:mod:`seatkit.body.parametric`: stature,
body mass index and proportions inside its ranges) is drawn again; the
number redrawn is reported. The tests check the marginals against the
survey's means and standard deviations.

The body (:func:`person_params`)
--------------------------------
Each person is the parametric body of their sex (``default-male`` /
``default-female``) with their stature and mass, and sitting height, hip
breadth, buttock-knee length and popliteal height as the model's inputs. The
model's inputs are not the measured figures: ``tools/fit_presets.py`` finds,
for the six percentile manikins, the inputs whose *measured* body has the
survey's figures. Here each survey figure is multiplied by the ratio
input / survey of the manikins of that sex, interpolated linearly in the
figure between the p5, p50 and p95 manikins (held at the ends).

Criteria (:data:`CRITERIA`, :func:`judge`)
------------------------------------------
A person is accommodated when every one holds (their limits are options):

``supported``
    the pressure problem on the design's contact set has a solution;
``no part cut``
    ``max_penetration_m`` and ``max_body_depth_m`` at most 5 mm (the
    build's guarantee);
``peak pressure``, ``joint moment``
    the largest contact pressure and the largest joint moment at most
    ``pressure_ratio`` / ``moment_ratio`` (default 2) times the largest the
    *reference* design gives its own sitters (its ``report.json``): the
    paper's model gives relative, not absolute, pressures. The reference is
    the design itself unless another build is named (``--reference``):
    designs compared on the same people must be judged against the same
    limits, and a shared design's own largest figures are those of the sitter
    it serves worst (a small woman on a large man's seat height), so its own
    limits are laxer than a one-person design's;
``seat height``
    the seat's front edge between ``seat_height_low`` (0.88) and
    ``seat_height_high`` (1.0) times the person's popliteal height plus the
    25 mm shoe allowance: the feet reach the floor and the thighs are not
    lifted off the seat (Parcells, Stommel and Hubbard 1999 recommend 88 to
    95 %; the upper end is widened to 100 %, where the feet still reach, as
    the rule "(popliteal height + shoes) cos 30 deg to cos 5 deg" of later
    school-furniture studies does: the lower leg 5 to 30 degrees from
    vertical, 87 to 99.6 %);
``seat depth``
    the loaded seat shorter than the person's buttock-popliteal length
    (ANSI/HFES 100-2007, 8.3.3: the front edge clears the back of the knee).

Outputs (in ``--out``)
----------------------
``people.csv`` (every person: inputs, figures, accommodated, reason),
``not-accommodated.csv`` (those not accommodated, with their reasons),
``accommodation.json`` (the criteria, shares overall and by sex, the
count of each reason and, in ``sole_reasons``, of the people whom one
criterion alone fails: what that criterion costs; the sampler's settings
and source), ``accommodation.png`` (accommodated or not
against stature and mass). Each person's result is written to
``people/NNNNN.json`` as it arrives; running the same command again skips
the people already done (the sample is the same for the same seed and N).
"""

from __future__ import annotations

import csv
import functools
import hashlib
import math
import io
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from seatkit.errors import InputError
from seatkit.resources import data_path

__all__ = [
    "CRITERIA",
    "Criteria",
    "judge",
    "load_population",
    "person_params",
    "run_accommodation",
    "sample_people",
]

#: Populations shipped (``seatkit/data/population/NAME.json``).
POPULATIONS = ("ansur-ii",)
#: Largest N one run takes.
MAX_PEOPLE = 100_000
#: The survey figures a person is drawn with (the statistics file's columns, in its order).
FIGURES = ("stature", "mass", "sitting_height", "hip_breadth", "buttock_knee", "popliteal_height", "buttock_popliteal_length")
#: The figures that are the parametric body's inputs besides stature and mass.
MODEL_INPUTS = ("sitting_height", "hip_breadth", "buttock_knee", "popliteal_height")
#: The knee's shape inputs (scales, no survey column of their own), interpolated over the manikins of the
#: person's sex by the survey figure they set: buttock-popliteal length for the calf's depth, stature for the knee's.
SHAPE_INPUTS = {"calf_depth": "buttock_popliteal_length", "knee_depth": "stature"}
#: Most redraws of one person before the sampler gives up (never reached with the shipped statistics).
MAX_REDRAWS = 1000


@functools.lru_cache(maxsize=None)
def load_population(name: str) -> dict:
    """The statistics file of population ``name`` (see the module docstring)."""
    if name not in POPULATIONS:
        raise InputError(f"--population: unknown population {name!r}; expected one of {', '.join(POPULATIONS)}")
    return json.loads(data_path("population", f"{name}.json").read_text(encoding="utf-8"))


@dataclass(frozen=True)
class Person:
    """One sampled person: an index, a sex and the survey figures (m, kg)."""

    index: int
    sex: str
    figures: dict

    @property
    def name(self) -> str:
        return f"{self.index:05d}-{self.sex}"


def _buildable(sex: str, f: dict) -> bool:
    """Whether the parametric body takes these figures (its accepted ranges)."""
    from seatkit.body import parametric as P

    s = f["stature"]
    checks = (
        (s, P.STATURE_RANGE),
        (f["mass"] / s**2, P.BMI_RANGE),
        (f["sitting_height"] / s, P.SITTING_RATIO_RANGE),
        (f["buttock_knee"] / s, P.BUTTOCK_KNEE_RATIO_RANGE),
        (f["hip_breadth"] / s, P.HIP_BREADTH_RATIO_RANGE),
        (f["popliteal_height"] / s, P.POPLITEAL_RATIO_RANGE),
    )
    return all(lo <= v <= hi for v, (lo, hi) in checks)


def sample_people(n: int, *, population: str = "ansur-ii", seed: int = 0, female_share: float = 0.5) -> tuple[list[Person], int]:
    """``n`` people drawn from the population (module docstring); and how many draws were redrawn."""
    if not 0.0 <= female_share <= 1.0:
        raise InputError(f"--female-share: expected a share from 0 to 1, got {female_share!r}")
    stats = load_population(population)
    cols = stats["columns"]
    people, redrawn = [], 0
    for i in range(n):
        rng = np.random.default_rng([seed, i])  # a person depends on the seed and their number only
        sex = "female" if rng.random() < female_share else "male"
        s = stats["sexes"][sex]
        mean, cov = np.asarray(s["mean_log"]), np.asarray(s["cov_log"])
        for _ in range(MAX_REDRAWS):
            figures = dict(zip(cols, (float(x) for x in np.exp(rng.multivariate_normal(mean, cov)))))
            if _buildable(sex, figures):
                break
            redrawn += 1
        else:  # pragma: no cover - the statistics would have to be far outside the model
            raise InputError(f"population {population}: no buildable person in {MAX_REDRAWS} draws")
        people.append(Person(i, str(sex), {k: round(v, 5) for k, v in figures.items()}))
    return people, redrawn


@functools.lru_cache(maxsize=None)
def _calibration(sex: str) -> dict:
    """Per model input: (survey values, input / survey ratios) of the p5, p50, p95 manikins of ``sex``."""
    from seatkit.body.presets import preset_table

    presets = [p for p in preset_table()["presets"].values() if p["sex"] == sex]
    presets.sort(key=lambda p: p["percentile"])
    out = {}
    for key in MODEL_INPUTS:
        survey = np.array([p["survey"][key] for p in presets])
        ratio = np.array([p["model_inputs"][key] / p["survey"][key] for p in presets])
        order = np.argsort(survey)
        out[key] = (survey[order], ratio[order])
    for key, by in SHAPE_INPUTS.items():
        if all(key in p["model_inputs"] for p in presets):
            survey = np.array([p["survey"][by] for p in presets])
            value = np.array([p["model_inputs"][key] for p in presets])
            order = np.argsort(survey)
            out[key] = (survey[order], value[order])
    return out


def person_params(person: Person) -> tuple[str, dict]:
    """The body model and its parameters for ``person`` (module docstring, "The body")."""
    cal = _calibration(person.sex)
    f = person.figures
    params = {"height": f["stature"], "mass": f["mass"]}
    for key in MODEL_INPUTS:
        xs, ratios = cal[key]
        params[key] = round(float(f[key] * np.interp(f[key], xs, ratios)), 5)
    for key, by in SHAPE_INPUTS.items():
        if key in cal:
            xs, values = cal[key]
            params[key] = round(float(np.interp(f[by], xs, values)), 5)
    return f"default-{person.sex}", params


@dataclass(frozen=True)
class Criteria:
    """The accommodation limits (module docstring, "Criteria")."""

    max_depth_m: float = 0.005
    pressure_ratio: float = 2.0
    moment_ratio: float = 2.0
    seat_height_low: float = 0.88
    seat_height_high: float = 1.0

    def describe(self, reference: dict) -> dict:
        whose = f"the reference design's ({reference['design']}) own sitters'" if reference.get("design") else "the design's own sitters'"
        return {
            "supported": "the pressure on the design's contact set has a solution",
            "no part cut": f"max_penetration_m and max_body_depth_m at most {self.max_depth_m * 1000:g} mm",
            "peak pressure": f"max_pressure_pa at most {self.pressure_ratio:g} x {whose} ({reference['max_pressure_pa']:.0f} Pa)",
            "joint moment": f"max_moment_nm at most {self.moment_ratio:g} x {whose} ({reference['max_moment_nm']:.1f} N m)",
            "seat height": f"{self.seat_height_low:g} to {self.seat_height_high:g} x (popliteal height + 25 mm shoe allowance)",
            "seat depth": "loaded seat depth shorter than the buttock-popliteal length",
        }


CRITERIA = Criteria()


def judge(metrics: dict, fit: dict, reference: dict, criteria: Criteria = CRITERIA) -> list[str]:
    """The reasons a person is not accommodated (empty: accommodated)."""
    if not metrics.get("supported"):
        # one reason: the solver's own sentence may hold the separator of reasons
        return [f"not supported: {str(metrics.get('reason') or 'no solution').replace('; ', ', ')}"]
    out = []
    depth = max(metrics["max_penetration_m"], metrics["max_body_depth_m"])
    if depth > criteria.max_depth_m:
        out.append(f"part cut: {depth * 1000:.1f} mm deep")
    if metrics["max_pressure_pa"] > criteria.pressure_ratio * reference["max_pressure_pa"]:
        out.append(f"peak pressure too high: {metrics['max_pressure_pa'] / 1000:.1f} kPa, over {criteria.pressure_ratio:g} x the design's own")
    if metrics["max_moment_nm"] > criteria.moment_ratio * reference["max_moment_nm"]:
        out.append(f"joint moment too high: {metrics['max_moment_nm']:.0f} N m, over {criteria.moment_ratio:g} x the design's own")
    seat, need = fit.get("seat_height_m"), fit.get("seat_height_for_shoes_m")
    if seat is None or need is None:
        out.append("not sitting on the seat (no loaded thighs)")
    else:
        ratio = seat / need
        if ratio > criteria.seat_height_high:
            out.append(f"seat too high: {ratio:.0%} of popliteal height + shoes")
        elif ratio < criteria.seat_height_low:
            out.append(f"seat too low: {ratio:.0%} of popliteal height + shoes")
    depth_diff = fit.get("seat_depth_difference_m")
    if depth_diff is not None and depth_diff >= 0.0:
        out.append(f"seat too deep: {depth_diff * 1000:.0f} mm past the back of the knee")
    return out


def design_reference(directory: Path) -> dict:
    """The largest peak pressure and joint moment the design gives its own sitters (its ``report.json``)."""
    path = Path(directory) / "report.json"
    try:
        ours = json.loads(path.read_text(encoding="utf-8"))["metrics"]["ours"]
        out = {
            key: max(float(m[key]) for m in ours if m.get("supported") is True)
            for key in ("max_pressure_pa", "max_moment_nm")
        }
        if not all(math.isfinite(v) and v > 0 for v in out.values()):
            raise ValueError
        return out
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError, AttributeError, RecursionError):
        raise InputError(
            f"{path}: expected the build's report.json with metrics.ours: the design's own sitters' "
            "max_pressure_pa and max_moment_nm (positive numbers)"
        ) from None


# ----------------------------------------------------------------------------- the work on Dask


@functools.lru_cache(maxsize=2)
def _worker_design(directory: str, stamp: float):
    """The design and a registry, read once per worker process (``stamp``: the file's mtime)."""
    from seatkit.plugins import get_plugin_manager
    from seatkit.trial import load_trial_design

    return load_trial_design(directory), get_plugin_manager().registry


def trial_task(directory: str, stamp: float, person: Person, pose: str) -> dict:
    """One person's trial on the design (run on a Dask worker): their figures, or their one-line error."""
    from seatkit.errors import SeatkitError

    start = time.process_time()
    design, registry = _worker_design(directory, stamp)
    model, params = person_params(person)
    from seatkit.trial import run_trial

    try:
        t = run_trial(design, registry, model, params, pose)
    except SeatkitError as e:
        return {"error": str(e).splitlines()[0], "cpu_s": time.process_time() - start}
    fit = {k: v for k, v in t.fit.items() if k != "measurements"}
    return {
        "metrics": t.metrics,
        "person_fit": fit,
        "placement": t.placement.report(),
        "cpu_s": time.process_time() - start,
    }


def _key(person: Person, pose: str) -> str:
    text = json.dumps([person.sex, person.figures, pose], sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_accommodation(
    directory,
    out,
    *,
    n: int,
    population: str = "ansur-ii",
    seed: int = 0,
    female_share: float = 0.5,
    pose: str = "upright-sitting",
    criteria: Criteria = CRITERIA,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    reference=None,
) -> dict:
    """The accommodation study (module docstring); returns what ``accommodation.json`` holds.

    ``reference`` is the build folder whose own sitters' largest figures set the pressure and
    moment limits (default: the design's own, ``directory``).
    """
    from seatkit.batch import dask_client
    from seatkit.io import jsonable, write_text_atomic
    from seatkit.trial import load_trial_design

    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_PEOPLE:
        raise InputError(f"--n: expected a whole number of people from 1 to {MAX_PEOPLE:,}, got {n!r}")
    directory = Path(directory)
    load_trial_design(directory)  # one line for a missing or broken design, before any work
    limits = design_reference(directory if reference is None else Path(reference))
    if reference is not None and Path(reference).resolve() != directory.resolve():
        limits["design"] = str(reference)  # named in the criteria: the limits are another build's
    reference = limits
    people, redrawn = sample_people(n, population=population, seed=seed, female_share=female_share)
    out = Path(out)
    (out / "people").mkdir(parents=True, exist_ok=True)
    results: dict[int, dict] = {}
    for p in people:  # resume: a person whose result is there (same sample, same pose) is done
        path = out / "people" / f"{p.name}.json"
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            if data.get("key") == _key(p, pose):
                results[p.index] = data
        except (OSError, ValueError):
            pass
    todo = [p for p in people if p.index not in results]
    skipped = len(results)
    if progress:
        progress(len(results), n)
    start = time.perf_counter()
    if todo:
        from dask.distributed import as_completed

        design_file = directory.resolve() / "design.npz"
        stamp = design_file.stat().st_mtime
        with dask_client(scheduler, workers) as client:
            futures = {
                client.submit(trial_task, str(directory.resolve()), stamp, p, pose, key=f"seatkit-trial-{p.name}-{_key(p, pose)}", pure=False): p
                for p in todo
            }
            for fut in as_completed(futures):
                p = futures[fut]
                try:
                    data = fut.result()
                except Exception as e:  # a crash of the worker itself
                    data = {"error": f"{type(e).__name__}: {e}".splitlines()[0]}
                data.update(key=_key(p, pose), sex=p.sex, figures=p.figures, params=person_params(p)[1])
                write_text_atomic(out / "people" / f"{p.name}.json", json.dumps(jsonable(data)) + "\n")
                results[p.index] = data
                if progress:
                    progress(len(results), n)
    seconds = time.perf_counter() - start
    return _write_outputs(out, directory, people, results, reference, criteria, {
        "population": population, "n": n, "seed": seed, "female_share": female_share, "pose": pose,
        "redrawn": redrawn, "run_now": len(todo), "already_done": skipped, "wall_seconds": seconds,
    })


def reason_heads(reason: str) -> list[str]:
    """The criteria a row's ``reason`` names (``"seat too high; part cut: ..."`` -> its heads); a person who could not be tried is one ``error``, whatever its message says."""
    if reason.startswith("error:"):
        return ["error"]
    return [part.split(":")[0] for part in reason.split("; ")]


def _rows(people, results, reference, criteria) -> list[dict]:
    rows = []
    for p in people:
        data = results[p.index]
        if "error" in data:
            reasons = [f"error: {data['error']}"]
            m, fit = {}, {}
        else:
            m, fit = data["metrics"], data["person_fit"]
            reasons = judge(m, fit, reference, criteria)
        rows.append({
            "person": p.name, "sex": p.sex, **{k: p.figures[k] for k in FIGURES},
            "accommodated": not reasons, "reason": "; ".join(reasons),
            **{k: m.get(k) for k in ("supported", "avg_distance_m", "max_penetration_m", "max_body_depth_m", "max_pressure_pa", "max_moment_nm")},
            **{k: fit.get(k) for k in ("seat_height_m", "seat_height_for_shoes_m", "seat_depth_m", "seat_depth_difference_m")},
            "cpu_s": data.get("cpu_s"),
        })
    return rows


def _csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    if rows:
        w = csv.DictWriter(buf, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else (f"{v:.6g}" if isinstance(v, float) else v)) for k, v in r.items()})
    return buf.getvalue()


def _share(rows) -> float | None:
    return sum(r["accommodated"] for r in rows) / len(rows) if rows else None


def _write_outputs(out: Path, directory: Path, people, results, reference, criteria, run: dict) -> dict:
    from seatkit.io import jsonable, write_text_atomic

    rows = _rows(people, results, reference, criteria)
    failed = [r for r in rows if not r["accommodated"]]
    reasons: dict[str, int] = {}
    sole: dict[str, int] = {}  # people failing one criterion only: the share that criterion alone costs
    for r in failed:
        heads = reason_heads(r["reason"])
        for head in heads:
            reasons[head] = reasons.get(head, 0) + 1
        if len(heads) == 1:
            sole[heads[0]] = sole.get(heads[0], 0) + 1
    cpu = [r["cpu_s"] for r in rows if isinstance(r["cpu_s"], (int, float))]
    stats = load_population(run["population"])
    summary = {
        "design": str(directory),
        "population": {"name": run["population"], "source": stats["source"], "distribution": stats["distribution"], "files_sha256": stats["files_sha256"]},
        "run": run,
        "criteria": criteria.describe(reference),
        "reference": reference,
        "n": len(rows),
        "accommodated": sum(r["accommodated"] for r in rows),
        "share": _share(rows),
        "share_by_sex": {s: _share([r for r in rows if r["sex"] == s]) for s in ("female", "male")},
        "reasons": dict(sorted(reasons.items(), key=lambda kv: -kv[1])),
        "sole_reasons": dict(sorted(sole.items(), key=lambda kv: -kv[1])),
        "cpu_seconds_per_person": float(np.mean(cpu)) if cpu else None,
        "files": {"people": "people.csv", "not_accommodated": "not-accommodated.csv", "plot": "accommodation.png"},
    }
    write_text_atomic(out / "people.csv", _csv(rows))
    write_text_atomic(out / "not-accommodated.csv", _csv([
        {k: r[k] for k in ("person", "sex", "stature", "mass", "popliteal_height", "buttock_popliteal_length", "reason")} for r in failed
    ]) or "person,sex,stature,mass,popliteal_height,buttock_popliteal_length,reason\n")
    from seatkit.picture.plot import write_accommodation_png

    write_accommodation_png(out / "accommodation.png", rows, title=f"{summary['accommodated']} of {len(rows)} accommodated ({summary['share']:.0%}) on {directory.name}")
    write_text_atomic(out / "accommodation.json", json.dumps(jsonable(summary), indent=1) + "\n")
    return summary


def share_text(summary: dict) -> str:
    """One line: the share accommodated, by sex."""
    by = summary["share_by_sex"]
    parts = [f"{s} {by[s]:.0%}" for s in ("female", "male") if by.get(s) is not None]
    return f"{summary['accommodated']} of {summary['n']} accommodated ({summary['share']:.1%}; {', '.join(parts)})" if summary["n"] else "nobody sampled"
