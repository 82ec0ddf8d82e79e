"""Compare two seatkit build folders file by file.

    python tools/compare_builds.py OLD NEW

Prints one line per file: ``same`` (byte-identical), ``only in OLD/NEW``, or
``differs`` with what differs. For the files whose content holds wall times
it also says whether they are the same apart from those: ``report.json``
(``timings_s``, the pressure's ``solve_seconds`` and every ``seconds`` of
the cage's meta left out), ``report.html``
(its "Time per stage" table left out) and ``design.npz`` (every array
compared; the header's JSON compared as data). Exits 1 when a file differs
in anything but wall times, else 0.
"""

from __future__ import annotations

import argparse
import io
import json
import re
import sys
import zipfile
from pathlib import Path

from seatkit.state import without_timings

_TIMES = re.compile(r"<!-- seatkit:timings -->.*?<!-- /seatkit:timings -->", re.S)


def _report_json(data: bytes):
    report = json.loads(data)
    report.pop("timings_s", None)
    for p in report.get("pressure", []):
        p.pop("solve_seconds", None)
    return without_timings(report)


def _report_html(data: bytes) -> str:
    return _TIMES.sub("", data.decode("utf-8"))


def _npz(data: bytes) -> dict:
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        return {name: zf.read(name) for name in zf.namelist()}


def compare_file(name: str, old: bytes, new: bytes) -> tuple[str, bool]:
    """(what differs, whether it is only wall times)."""
    if old == new:
        return "same", True
    if name == "report.json":
        a, b = _report_json(old), _report_json(new)
        keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        if not keys:
            return "differs only in timings_s, solve_seconds and the refiners' seconds (wall times)", True
        return f"differs beyond the wall times, in {', '.join(keys)}", False
    if name == "report.html":
        if _report_html(old) == _report_html(new):
            return "differs only in its time-per-stage table (wall times)", True
        return "differs beyond its time-per-stage table", False
    if name.endswith(".npz"):
        a, b = _npz(old), _npz(new)
        diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        return f"differs in the arrays {', '.join(diff)}", False
    return f"differs ({len(old)} and {len(new)} bytes)", False


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", type=Path)
    ap.add_argument("new", type=Path)
    args = ap.parse_args(argv)
    for folder in (args.old, args.new):
        if not folder.is_dir():
            print(f"{folder}: not a folder", file=sys.stderr)
            return 2
    names = sorted({p.name for p in args.old.iterdir()} | {p.name for p in args.new.iterdir()})
    ok = True
    for name in names:
        a, b = args.old / name, args.new / name
        if not a.is_file() or not b.is_file():
            print(f"{name}: only in {args.old if a.is_file() else args.new}")
            ok = False
            continue
        what, fine = compare_file(name, a.read_bytes(), b.read_bytes())
        print(f"{name}: {what}")
        ok &= fine
    print("same but for wall times" if ok else "DIFFERENT")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
