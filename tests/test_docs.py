"""The documentation stays true: its commands run as written, its generated pages are current, the site builds.

- Every ``bash`` block of ``docs/`` runs as written, one command after the
  other, in one fresh folder that holds what a clone gives (``examples/``),
  pages in the order of the site's navigation (``mkdocs.yml``). A command
  that appears on several pages runs once.
- A block that must not run in the suite is marked on the line before its
  fence with ``<!-- docs-test: skip REASON -->`` (``seatkit serve`` runs
  until stopped, a benchmark takes minutes, ``pip install`` of a plugin
  changes the environment). Such a block is still checked: its script or
  sub-command exists and takes every option the block gives it.
- The install steps (``pip install .`` and its extras, the setup script,
  ``pytest``) are what ``.ci/run`` runs on a fresh virtual environment; here
  they are recognised and left out.
- ``tools/make_reference.py --check``: the generated reference pages and
  option tables are what the code gives.
- ``mkdocs build --strict``: the site builds with no warning (a broken link
  or anchor fails).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
SKIP = re.compile(r"<!--\s*docs-test:\s*skip\s+(.+?)\s*-->\s*$")
FENCE = re.compile(r"^```bash\s*$")

#: Install and test steps: CI's .ci/run does these on a fresh environment.
SETUP = re.compile(r"^(pip install (\.|'\.\[[\w,]+\]')|bash tools/setup-system\.sh( --test)?|pytest)$")


def _nav_pages() -> list[Path]:
    """docs/ pages in the order of mkdocs.yml's nav, then any page the nav leaves out (none should be)."""

    def walk(items):
        for item in items:
            value = next(iter(item.values())) if isinstance(item, dict) else item
            if isinstance(value, list):
                yield from walk(value)
            elif isinstance(value, str) and value.endswith(".md"):
                yield DOCS / value

    config = yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=yaml.BaseLoader)
    ordered = list(dict.fromkeys(walk(config["nav"])))
    rest = sorted(set(DOCS.rglob("*.md")) - set(ordered))
    return ordered + rest


def doc_blocks() -> list[tuple[Path, int, str | None, list[str]]]:
    """Every bash block of docs/: (page, line, skip reason or None, its commands)."""
    out = []
    for page in _nav_pages():
        lines = page.read_text(encoding="utf-8").splitlines()
        i = 0
        while i < len(lines):
            if not FENCE.match(lines[i]):
                i += 1
                continue
            marker = SKIP.match(lines[i - 1]) if i else None
            start, body = i + 1, []
            i += 1
            while i < len(lines) and lines[i].strip() != "```":
                body.append(lines[i])
                i += 1
            out.append((page, start, marker.group(1) if marker else None, _commands("\n".join(body))))
            i += 1
    return out


def _commands(block: str) -> list[str]:
    """The commands of a block: continuations joined, comments removed, ``&&`` chains split."""
    joined = re.sub(r"\\\n\s*", " ", block)
    commands = []
    for line in joined.splitlines():
        if not shlex.split(line, comments=True):
            continue
        text = line.split(" #", 1)[0]  # a trailing comment (as the README test reads them)
        commands.extend(c.strip() for c in re.split(r"\s&&\s", text.strip()) if c.strip())
    return commands


def _seatkit_bin() -> str:
    found = Path(sys.executable).parent / "seatkit"
    return str(found) if found.exists() else shutil.which("seatkit")


def _env() -> dict:
    env = {**os.environ, "PATH": f"{Path(_seatkit_bin()).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.setdefault("SEATKIT_DISABLE_PLUGIN_AUTOLOAD", "1")
    return env


def test_every_docs_block_is_run_or_marked_and_every_command_is_known():
    blocks = doc_blocks()
    assert len(blocks) >= 10
    for page, line, reason, commands in blocks:
        where = f"{page.relative_to(ROOT)}:{line}"
        assert commands, f"{where}: an empty bash block"
        if reason is not None:
            assert len(reason) > 10, f"{where}: a skip marker must say why the block does not run"
            continue
        for command in commands:
            first = shlex.split(command)[0]
            assert SETUP.match(command) or first in ("seatkit", "python", "cat", "ls"), (
                f"{where}: {command!r} is neither a seatkit/python command this test runs nor an install step; "
                "mark its block <!-- docs-test: skip REASON --> if it must not run"
            )


def _options_of(command: str) -> list[str]:
    return [w.split("=", 1)[0] for w in shlex.split(command) if w.startswith("--")]


def _wrapped(command: str) -> list[str]:
    """``command``, and the command it runs after a bare ``--`` (``python a.py run X -- b.py --opt``: ``python b.py --opt``)."""
    words = shlex.split(command)
    if "--" not in words:
        return [command]
    cut = words.index("--")
    inner = words[cut + 1 :]
    return [shlex.join(words[:cut]), *(_wrapped(shlex.join(["python", *inner])) if inner[:1] and inner[0].endswith(".py") else [])]


def test_the_skipped_blocks_name_commands_and_options_that_exist(tmp_path):
    """A block that does not run still names a script or sub-command that exists, with options it takes."""
    env = _env()
    helps: dict[tuple, str] = {}
    for page, line, reason, commands in doc_blocks():
        if reason is None:
            continue
        for command in (c for whole in commands for c in _wrapped(whole)):
            words = shlex.split(command)
            if words[0] == "seatkit":
                key = tuple(w for w in words[1:2] if not w.startswith("-"))
            elif words[0] == "python" and words[1].endswith(".py"):
                assert (ROOT / words[1]).exists(), f"{page.relative_to(ROOT)}:{line}: {words[1]} does not exist"
                key = ("python", words[1])
            else:
                continue  # pip, bash: install steps
            if key not in helps:
                argv = [_seatkit_bin(), *key, "--help"] if words[0] == "seatkit" else [sys.executable, str(ROOT / key[1]), "--help"]
                done = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
                assert done.returncode == 0, f"{page.relative_to(ROOT)}:{line}: {' '.join(argv)}\n{done.stderr}"
                helps[key] = done.stdout
            for option in _options_of(command):
                assert option in helps[key], f"{page.relative_to(ROOT)}:{line}: {command!r}: {' '.join(key)} has no option {option}"


def test_the_generated_reference_is_current():
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        from make_reference import stale
    finally:
        sys.path.remove(str(ROOT / "tools"))
    assert stale() == [], "run python tools/make_reference.py"


def test_the_metrics_module_names_every_figure_the_report_shows():
    from seatkit.export.report import table_rows
    from seatkit.metrics import CHECKS, PAPER_TABLE1, TABLE

    _, labels = table_rows({"ours": [{}], "baseline": [{}]})
    assert labels == [m.label for m in TABLE]
    assert TABLE == PAPER_TABLE1 + CHECKS and len(PAPER_TABLE1) == 5
    assert len({m.key for m in TABLE}) == len(TABLE)


def test_the_example_body_is_what_its_tool_writes(tmp_path):
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        from make_example_body import DEFAULT_OUT, write_example_body
    finally:
        sys.path.remove(str(ROOT / "tools"))
    fresh = write_example_body(tmp_path / "body.glb")
    assert fresh.read_bytes() == DEFAULT_OUT.read_bytes(), "run python tools/make_example_body.py"


def test_the_site_builds_strictly(tmp_path):
    """mkdocs build --strict: any warning (a broken link or anchor, a page left out of the nav) fails."""
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},  # Material's banner about its successor, not a warning of ours
    )
    assert done.returncode == 0, done.stderr[-4000:]
    assert (tmp_path / "site" / "index.html").exists()
    assert (tmp_path / "site" / "reference" / "cli" / "index.html").exists()


@pytest.mark.slow
def test_every_docs_command_works_as_written_in_a_fresh_folder(tmp_path):
    pytest.importorskip("dask.distributed")  # seatkit batch and sweep need the batch extra (in [test])
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    env = _env()
    done_commands: set[str] = set()
    report_checked = False
    for page, line, reason, commands in doc_blocks():
        if reason is not None:
            continue
        for command in commands:
            if SETUP.match(command) or command in done_commands:
                continue
            done_commands.add(command)
            done = subprocess.run(["bash", "-c", command], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
            assert done.returncode == 0, f"{page.relative_to(ROOT)}:{line}: {command}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
            words = shlex.split(command)
            if words[:2] == ["seatkit", "build"] and not report_checked:
                (folder,) = re.findall(r"wrote \d+ files to (\S+)", done.stderr)
                report = json.loads((tmp_path / folder / "report.json").read_text())
                _assert_metrics_documented(report["metrics"])
                report_checked = True
    assert report_checked and len(done_commands) >= 10


def _assert_metrics_documented(metrics: dict) -> None:
    """Every per-person figure and dimension of report.json is named in seatkit.metrics (so in the reference page)."""
    from seatkit.metrics import DIMENSIONS, INTERFACE, OTHER, PERSON_FIT, TABLE

    named = {m.key for m in TABLE + OTHER} | {"supported", "reason"}
    for person in metrics["ours"] + metrics.get("baseline", []):
        assert set(person) <= named, f"report.json figures not in seatkit.metrics: {sorted(set(person) - named)}"
    assert {m.key for m in TABLE} <= set(metrics["ours"][0])
    for dims in metrics["dimensions"]:
        assert set(dims) == {m.key for m in DIMENSIONS}
    for fit in metrics["person_fit"]:  # the seat's own dimensions, the person's, the standard and the raw measurements
        assert {m.key for m in PERSON_FIT} <= set(fit) - {"standard", "measurements"} <= {m.key for m in DIMENSIONS + PERSON_FIT}
    for figures in metrics["interface"]:  # the figures, the model's name and meaning, the load shares and friction
        assert set(figures) - {"supported", "model", "meaning", "load_share", "friction"} == {m.key for m in INTERFACE}
