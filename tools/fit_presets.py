"""Fit the percentile manikins (p5/p50/p95, female/male) to the ANSUR II survey.

    python tools/fit_presets.py /path/to/ansur-ii-csv-folder
    python tools/fit_presets.py /path/to/ansur-ii-csv-folder --percentiles default-male,default-female

reads ``ANSUR_II_MALE_Public.csv`` and ``ANSUR_II_FEMALE_Public.csv`` (the
ANSUR II public release, Gordon et al. 2014; millimetres, ``weightkg`` in
tenths of a kilogram), takes the 5th, 50th and 95th percentile of each
measurement (numpy's default linear interpolation, unweighted), and finds
the parametric model's inputs whose *measured* sitting height, hip breadth
(sitting), buttock-knee length, popliteal height, knee height sitting and
buttock-popliteal length (``seatkit.body.measure``) equal the survey's: the
first four by a few fixed-point steps, the last two through the knee's two
depth scales (``knee_depth``, ``calf_depth``) by a secant step each. Writes
``seatkit/data/bodies/presets.yaml``. With ``--percentiles BODIES`` it
writes nothing and prints, for each body, its measurements and the share
of the survey's people of its sex below each (unweighted), the table of
``docs/bodies.md`` ("The default bodies: who they are").
"""

from __future__ import annotations

import csv
import hashlib
import sys
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parent.parent
OUT = REPO / "seatkit" / "data" / "bodies" / "presets.yaml"
COLUMNS = {
    "stature": "stature",
    "mass": "weightkg",
    "sitting_height": "sittingheight",
    "hip_breadth": "hipbreadthsitting",
    "buttock_knee": "buttockkneelength",
    "popliteal_height": "poplitealheight",
    "knee_height_sitting": "kneeheightsitting",
    "buttock_popliteal_length": "buttockpopliteallength",
    "thigh_clearance": "thighclearance",
    "elbow_rest_height": "elbowrestheight",
    "waist_circumference": "waistcircumference",
    "buttock_circumference": "buttockcircumference",
}
MEASURED = {
    "sitting_height": "sitting_height",
    "hip_breadth": "hip_breadth_sitting",
    "buttock_knee": "buttock_knee_length",
    "popliteal_height": "popliteal_height",
}


def survey(folder: Path) -> tuple[dict, dict]:
    out, files = {}, {}
    for sex in ("male", "female"):
        path = folder / f"ANSUR_II_{sex.upper()}_Public.csv"
        files[path.name] = hashlib.sha256(path.read_bytes()).hexdigest()
        with path.open(encoding="latin-1") as f:
            rows = list(csv.DictReader(f))
        for p in (5, 50, 95):
            fig = {}
            for key, col in COLUMNS.items():
                v = np.array([float(r[col]) for r in rows])
                scale = 0.1 if key == "mass" else 0.001
                fig[key] = round(float(np.percentile(v, p)) * scale, 4)
            fig["n"] = len(rows)
            out[f"p{p}-{sex}"] = fig
    return out, files


#: The knee's two depth scales and the survey figure each is fitted to.
KNEE = {"knee_depth": "knee_height_sitting", "calf_depth": "buttock_popliteal_length"}
#: Seated, about how much of the knee's thickness (knee height sitting less popliteal height) and depth
#: (buttock-knee less buttock-popliteal length) a unit of ``knee_depth`` and ``calf_depth`` moves:
#: the first step's slope, measured on the presets; later steps use the secant.
KNEE_GAIN = {"knee_depth": 0.6, "calf_depth": 0.45}


def _knee_sizes(m: dict) -> dict:
    """The knee's seated thickness and depth, m: what ``knee_depth`` and ``calf_depth`` set."""
    return {
        "knee_depth": m["knee_height_sitting"] - m["popliteal_height"],
        "calf_depth": m["buttock_knee_length"] - m["buttock_popliteal_length"],
    }


def fit(name: str, fig: dict, steps: int = 30) -> dict:
    """The model's inputs whose measured body matches the survey: sitting height, hip breadth, buttock-knee
    length and popliteal height to 0.1 %, knee height sitting and buttock-popliteal length to 0.2 %.

    The four lengths by a fixed point on their ratio to the survey; the two knee scales by a secant step
    each on the knee's thickness and depth (their slopes start from :data:`KNEE_GAIN`).
    """
    from seatkit.body.measure import measure_rig
    from seatkit.body.parametric import make_parametric_body

    sex = name.split("-")[1]
    inputs = {k: fig[k] for k in MEASURED} | {k: 1.0 for k in KNEE}
    want = {"knee_depth": fig["knee_height_sitting"] - fig["popliteal_height"]}
    want["calf_depth"] = fig["buttock_knee"] - fig["buttock_popliteal_length"]
    previous = None
    for _ in range(steps):
        rig = make_parametric_body(sex, stature=fig["stature"], mass=fig["mass"], **inputs)
        m = measure_rig(rig).as_dict()
        err = {k: m[MEASURED[k]] / fig[k] - 1.0 for k in MEASURED}
        knee_err = {k: m[figure] / fig[figure] - 1.0 for k, figure in KNEE.items()}
        if max(abs(e) for e in err.values()) < 1e-3 and max(abs(e) for e in knee_err.values()) < 2e-3:
            break
        sizes = _knee_sizes(m)
        update = {k: inputs[k] / (1.0 + err[k]) for k in MEASURED}
        for k in KNEE:
            slope = KNEE_GAIN[k] * sizes[k]
            if previous is not None and abs(inputs[k] - previous[0][k]) > 1e-4:
                secant = (sizes[k] - previous[1][k]) / (inputs[k] - previous[0][k])
                slope = secant if secant > 0.1 * slope else slope
            update[k] = float(min(max(inputs[k] + (want[k] - sizes[k]) / slope, 0.55), 1.45))
        previous = (dict(inputs), sizes)
        inputs = update
    else:
        raise SystemExit(f"{name}: the fit did not converge in {steps} steps ({err}, {knee_err})")
    return {k: round(float(v), 5) for k, v in inputs.items()}, m


def percentiles(folder: Path, names: list[str]) -> None:
    from seatkit.body import load_rig
    from seatkit.body.measure import measure_rig

    print("| body | dimension | measured | percentile |")
    print("|---|---|---|---|")
    for name in names:
        rig = load_rig(name)
        sex = rig.meta.get("sex", "male")
        with (folder / f"ANSUR_II_{sex.upper()}_Public.csv").open(encoding="latin-1") as f:
            rows = list(csv.DictReader(f))
        m = measure_rig(rig).as_dict()
        keys = {"mass": "mass", "sitting_height": "sitting_height", "hip_breadth": "hip_breadth_sitting"}
        keys |= {"buttock_knee": "buttock_knee_length", "buttock_circumference": "hip_circumference"}
        for key, col in COLUMNS.items():
            value = m[keys.get(key, key)]
            survey = np.array([float(r[col]) for r in rows]) * (0.1 if key == "mass" else 0.001)
            unit = "kg" if key == "mass" else "m"
            print(f"| {name} | {key} | {value:.3f} {unit} | {100 * np.mean(survey < value):.0f} |")


def main() -> None:
    folder = Path(sys.argv[1])
    if len(sys.argv) == 4 and sys.argv[2] == "--percentiles":
        percentiles(folder, sys.argv[3].split(","))
        return
    figures, files = survey(folder)
    presets = {}
    for name, fig in figures.items():
        inputs, m = fit(name, fig)
        presets[name] = {"sex": name.split("-")[1], "percentile": int(name[1:].split("-")[0]), "survey": fig, "model_inputs": inputs}
        print(name, fig, inputs, {k: round(v, 4) for k, v in m.items()}, flush=True)
    doc = {
        "source": "ANSUR II public data (Gordon et al. 2014, NATICK/TR-15/007): percentiles of the unweighted "
        "public release, computed by tools/fit_presets.py",
        "files_sha256": files,
        "units": "m and kg",
        "presets": presets,
    }
    OUT.write_text("# Written by tools/fit_presets.py; see docs/bodies.md.\n" + yaml.safe_dump(doc, sort_keys=False))


if __name__ == "__main__":
    main()
