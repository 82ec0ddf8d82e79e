"""Every command of the README's code blocks, run as written in a fresh folder.

The folder holds what a fresh clone gives the commands (``examples/``) and
nothing else; the commands run one after the other through a shell, as a new
user would type them. The install and test steps of the Quick start (the
setup script, ``pip install``, ``pytest``) are what CI's ``.ci/run`` runs
verbatim on a fresh virtual environment; here they are recognised and left
out, and any other command the README gains must be run here or the test fails.
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

ROOT = Path(__file__).resolve().parents[1]

#: The Quick start's install and test steps (run by .ci/run, not here).
SETUP_STEPS = {
    "bash tools/setup-system.sh",
    "bash tools/setup-system.sh --test",
    "pip install .",
    "pip install '.[test]'",
    "pytest",
}


def readme_commands() -> list[str]:
    """Each command of the README's ``bash`` blocks, comments removed, ``&&`` chains split."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            words = shlex.split(line, comments=True)
            if not words:
                continue
            # split the chain on && (as the shell would), keeping each command's own quoting
            chain = re.split(r"\s&&\s", line.split(" #", 1)[0].strip())
            commands.extend(c.strip() for c in chain if c.strip())
    return commands


def _seatkit_bin() -> str:
    found = Path(sys.executable).parent / "seatkit"
    return str(found) if found.exists() else shutil.which("seatkit")


def _pose_args(words: list[str]) -> list[str]:
    return [words[i + 1] for i, w in enumerate(words[:-1]) if w in ("--pose", "-p")]


def test_the_readme_commands_are_the_ones_this_test_knows():
    commands = readme_commands()
    assert "seatkit build --template chair" in commands
    assert any(c.startswith("seatkit batch ") for c in commands)
    others = [c for c in commands if not c.startswith("seatkit ") and c not in SETUP_STEPS]
    assert others == [], "a README command this test neither runs nor knows as a setup step"


@pytest.mark.slow
def test_every_readme_command_works_as_written_in_a_fresh_folder(tmp_path):
    pytest.importorskip("dask.distributed")  # the batch line needs the batch extra (in [test])
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    env = {**os.environ, "PATH": f"{Path(_seatkit_bin()).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.setdefault("SEATKIT_DISABLE_PLUGIN_AUTOLOAD", "1")
    builds: dict[str, list[str]] = {}  # output folder -> the poses its command asked for
    ran = []
    for command in readme_commands():
        if command in SETUP_STEPS:
            continue
        done = subprocess.run(["bash", "-c", command], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"{command}\n{done.stdout}\n{done.stderr}"
        ran.append(command)
        words = shlex.split(command)
        if words[1] == "build":
            (folder,) = re.findall(r"wrote \d+ files to (\S+)", done.stderr)
            assert folder not in builds, f"{command} wrote into {folder}, as an earlier README build did"
            builds[folder] = _pose_args(words)
        if words[1] == "evaluate":
            assert "ours" in done.stdout and "flat-patch" in done.stdout
            assert (tmp_path / words[2] / "evaluation.json").exists()
            # every figure the report shows, for the design the README built first
            html = (tmp_path / words[2] / "report.html").read_text()
            for label in ("avg. dist.", "avg. moment", "max. moment", "avg. press.", "max. press.", "max. penetration", "max. body depth"):
                assert label in done.stdout and f"<td>{label}</td>" in html
            assert "person 1: upright-sitting, default-male, 75 kg" in done.stdout
            assert "<td>export</td>" in html and "<th>total</th>" in html
        if words[1] == "batch":
            out = tmp_path / words[words.index("--out") + 1]
            poses = sorted(p.stem for p in (tmp_path / words[2]).glob("*.yaml"))
            assert poses and sorted(p.name for p in out.iterdir() if p.is_dir()) == poses
            assert all((out / name / ".seatkit-run").exists() for name in poses)
        if words[1] == "pressure":
            weight, reaction = re.search(r"total reaction ([\d.]+) N \(weight ([\d.]+) N\)", done.stdout).groups()
            assert float(weight) == pytest.approx(float(reaction), rel=1e-3)
    assert len(builds) >= 4
    # none of the builds replaced another's output: each folder still holds its own design
    for folder, poses in builds.items():
        report = json.loads((tmp_path / folder / "report.json").read_text())
        got = [Path(b["pose"]).stem for b in report["recipe"]["bodies"]]
        assert got == (poses or got), f"{folder} holds {got}, not the {poses} its command built"
    assert "seatkit-out/chair-upright-sitting" in builds
    assert len(ran) >= 8
