"""``seatkit serve`` as a command: it serves the page and its vendored three.js, warns off localhost, and names the pip extra when it is missing."""

from __future__ import annotations

import socket
import subprocess
import sys
import time

import pytest

httpx = pytest.importorskip("httpx")
pytest.importorskip("uvicorn")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _serve(tmp_path, *flags):
    port = _free_port()
    cmd = [sys.executable, "-m", "seatkit.cli", "serve", "--no-browser", "--port", str(port), "--folder", str(tmp_path / "srv"), *flags]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return proc, port


def _wait(proc, url):
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"seatkit serve exited: {proc.stderr.read()}")
        try:
            return httpx.get(url, timeout=5)
        except httpx.TransportError:
            time.sleep(0.1)
    pytest.fail("seatkit serve did not answer within 60 s")


def _stop(proc) -> str:
    proc.terminate()
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return err


def test_serve_serves_the_page_offline(tmp_path):
    proc, port = _serve(tmp_path)
    try:
        base = f"http://127.0.0.1:{port}"
        page = _wait(proc, base + "/")
        assert page.status_code == 200
        assert "/static/app.js" in page.text and '"three": "/static/vendor/three.module.js"' in page.text
        assert "http://" not in page.text and "https://" not in page.text  # nothing from elsewhere
        for path in ("/static/app.js", "/static/vendor/three.module.js", "/static/vendor/three.core.js", "/static/vendor/OrbitControls.js"):
            r = httpx.get(base + path, timeout=10)
            assert r.status_code == 200, path
        js = httpx.get(base + "/static/app.js", timeout=10).text
        assert "https://" not in js and "http://" not in js
        assert httpx.get(base + "/api/options", timeout=30).json()["default_template"] == "chair"
    finally:
        err = _stop(proc)
    assert "warning" not in err  # localhost: no warning
    assert f"http://127.0.0.1:{port}/" in err


def test_serve_warns_off_localhost(tmp_path):
    proc, port = _serve(tmp_path, "--host", "127.0.0.2")
    try:
        assert _wait(proc, f"http://127.0.0.2:{port}/api/status").status_code == 200
    finally:
        err = _stop(proc)
    assert "seatkit: warning: listening on 127.0.0.2" in err and "no login" in err


def test_serve_names_the_extra_when_it_is_missing(monkeypatch):
    from typer.testing import CliRunner

    from seatkit.cli import app

    monkeypatch.setitem(sys.modules, "uvicorn", None)  # import uvicorn -> ImportError
    out = CliRunner().invoke(app, ["serve", "--no-browser"])
    assert out.exit_code == 1
    text = out.stderr if hasattr(out, "stderr") else out.output
    assert "pip install 'seatkit[serve]'" in text


def test_serve_refuses_a_bad_port():
    from typer.testing import CliRunner

    from seatkit.cli import app

    out = CliRunner().invoke(app, ["serve", "--no-browser", "--port", "70000"])
    assert out.exit_code == 1
    assert "--port: expected a port number between 1 and 65535, got 70000" in (out.stderr if hasattr(out, "stderr") else out.output)


def test_serve_says_when_the_port_is_taken(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        done = subprocess.run(
            [sys.executable, "-m", "seatkit.cli", "serve", "--no-browser", "--port", str(port), "--folder", str(tmp_path / "srv")],
            capture_output=True,
            text=True,
            timeout=120,
        )
    assert done.returncode == 1
    assert f"seatkit: error: could not listen on 127.0.0.1:{port} (is the port in use? try --port)" in done.stderr
