"""Fit the percentile manikins (p5/p50/p95, female/male) to the ANSUR II survey.

    python tools/fit_presets.py /path/to/ansur-ii-csv-folder
    python tools/fit_presets.py /path/to/ansur-ii-csv-folder --percentiles default-male,default-female

reads ``ANSUR_II_MALE_Public.csv`` and ``ANSUR_II_FEMALE_Public.csv`` (the
ANSUR II public release, Gordon et al. 2014; millimetres, ``weightkg`` in
tenths of a kilogram), takes the 5th, 50th and 95th percentile of each
measurement (numpy's default linear interpolation, unweighted), and finds
the parametric model's inputs whose *measured* sitting height, hip breadth
(sitting) and buttock-knee length (``seatkit.body.measure``) equal the
survey's, by a few fixed-point steps per measurement. Writes
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


def fit(name: str, fig: dict) -> dict:
    from seatkit.body.measure import measure_rig
    from seatkit.body.parametric import make_parametric_body

    sex = name.split("-")[1]
    inputs = {k: fig[k] for k in MEASURED}
    for _ in range(10):
        rig = make_parametric_body(sex, stature=fig["stature"], mass=fig["mass"], **inputs)
        m = measure_rig(rig).as_dict()
        err = {k: m[MEASURED[k]] / fig[k] - 1.0 for k in MEASURED}
        if max(abs(e) for e in err.values()) < 1e-3:
            break
        inputs = {k: inputs[k] / (1.0 + err[k]) for k in MEASURED}
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
