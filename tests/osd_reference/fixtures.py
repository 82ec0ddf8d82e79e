"""Pytest fixtures for the OpenSubdiv comparison (import them into a test module).

``osd_reference`` compiles ``osd_reference.cpp`` once per session (cached
across sessions by source hash). Without g++ or libosd-dev it skips, or
fails when the ``CI`` environment variable is set: CI must run the
comparison.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

_HERE = Path(__file__).resolve().parent


def load_runner():
    """The ``runner`` helper module beside this file (importable in any pytest import mode)."""
    name = "seatkit_tests_osd_runner"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, _HERE / "runner.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def osd_reference(tmp_path_factory):
    """Path of the compiled OpenSubdiv reference program."""
    runner = load_runner()
    try:
        return runner.compile_reference()
    except PermissionError:
        return runner.compile_reference(tmp_path_factory.mktemp("osd"))
    except runner.ReferenceUnavailable as exc:
        if os.environ.get("CI"):
            pytest.fail(f"OpenSubdiv reference unavailable in CI: {exc}")
        pytest.skip(f"OpenSubdiv reference unavailable: {exc}")
