"""Install hints name steps and extras that exist."""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

import pytest

from seatkit.errors import SeatkitError

ROOT = Path(__file__).resolve().parents[1]


def _extras() -> set[str]:
    return set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"])


def test_every_extra_named_in_the_code_and_docs_exists():
    named = {}
    for path in [*ROOT.glob("seatkit/**/*.py"), *ROOT.glob("plugins/**/*.py"), *ROOT.glob("docs/*.md"), ROOT / "README.md"]:
        text = path.read_text(encoding="utf-8")
        for extra in re.findall(r"(?:seatkit|(?<=['\"\s])\.)\[([a-z0-9_-]+)\]", text):
            named.setdefault(extra, path.relative_to(ROOT))
        for extra in re.findall(r"MissingExtraError\([^)]*?,\s*\"([a-z0-9_-]+)\"", text):
            named.setdefault(extra, path.relative_to(ROOT))
    missing = {extra: str(path) for extra, path in named.items() if extra not in _extras()}
    assert "anny" in named and "batch" in named
    assert missing == {}, f"extras named but not in pyproject.toml: {missing}"


def test_a_missing_usd_core_names_the_package_not_an_extra(monkeypatch):
    from seatkit.export import usd

    monkeypatch.setitem(sys.modules, "pxr", None)  # import pxr -> ImportError
    with pytest.raises(SeatkitError) as info:
        usd._pxr()
    assert str(info.value) == (
        "writing USD needs the package 'usd-core', a dependency of seatkit that is missing: pip install 'usd-core>=24.0'"
    )
