"""Derive the population statistics ``seatkit accommodate`` samples from: ANSUR II, per sex.

    python tools/make_population_stats.py /path/to/ansur-ii-csv-folder

reads ``ANSUR_II_MALE_Public.csv`` and ``ANSUR_II_FEMALE_Public.csv`` (the
ANSUR II public release, Gordon et al. 2014; public-domain US Army data;
millimetres, ``weightkg`` in tenths of a kilogram) and writes
``seatkit/data/population/ansur-ii.json``: per sex, the number of people,
the mean and covariance of the *natural logarithms* of the columns the
parametric body takes (stature, mass, sitting height, hip breadth sitting,
buttock-knee length, popliteal height) and of the buttock-popliteal length
the seat-depth criterion reads, in metres and kilograms; and, for checks,
the plain mean, standard deviation and 1st/99th percentiles of each. The
CSVs are not shipped; their SHA-256 and this command are written with the
figures. Statistics are unweighted (the public release's own sample).
"""

from __future__ import annotations

import csv
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
from fit_presets import COLUMNS as SURVEY_COLUMNS  # tools/ is this script's folder

REPO = Path(__file__).resolve().parent.parent
OUT = REPO / "seatkit" / "data" / "population" / "ansur-ii.json"
#: Our name -> ANSUR II column (tools/fit_presets.py's names); all millimetres but weightkg (tenths of a kg).
COLUMNS = {key: SURVEY_COLUMNS[key] for key in (
    "stature", "mass", "sitting_height", "hip_breadth", "buttock_knee", "popliteal_height", "buttock_popliteal_length",
)}


def statistics(folder: Path) -> dict:
    out = {
        "source": "ANSUR II public data (Gordon et al. 2014, NATICK/TR-15/007), US Army, public domain; unweighted",
        "command": "python tools/make_population_stats.py ANSUR_II_CSV_FOLDER",
        "distribution": "multivariate log-normal per sex: log(values) ~ N(mean_log, cov_log)",
        "units": "m and kg",
        "columns": list(COLUMNS),
        "files_sha256": {},
        "sexes": {},
    }
    for sex in ("male", "female"):
        path = folder / f"ANSUR_II_{sex.upper()}_Public.csv"
        out["files_sha256"][path.name] = hashlib.sha256(path.read_bytes()).hexdigest()
        with path.open(encoding="latin-1", newline="") as f:
            rows = list(csv.DictReader(f))
        x = np.array([[float(r[c]) * (0.1 if key == "mass" else 0.001) for key, c in COLUMNS.items()] for r in rows])
        logs = np.log(x)
        out["sexes"][sex] = {
            "n": len(rows),
            "mean_log": np.round(logs.mean(axis=0), 8).tolist(),
            "cov_log": np.round(np.cov(logs, rowvar=False), 10).tolist(),
            "mean": np.round(x.mean(axis=0), 5).tolist(),
            "sd": np.round(x.std(axis=0, ddof=1), 5).tolist(),
            "p1": np.round(np.percentile(x, 1, axis=0), 4).tolist(),
            "p99": np.round(np.percentile(x, 99, axis=0), 4).tolist(),
        }
    return out


def main() -> None:
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    data = statistics(Path(sys.argv[1]))
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
