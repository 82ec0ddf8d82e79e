"""``seatkit serve`` against an attacker on the loopback: every abuse gets a 4xx with one line.

Pose ``base:`` files outside the server's pose folders, oversized or deeply
nested JSON, sequence numbers that are not plain digits, a refused request
trying to cancel the running design, unbounded work per request, and the
upload folder growing without end.
"""

from __future__ import annotations

import json
import threading
import warnings

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytest.importorskip("starlette")
pytest.importorskip("httpx")

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from starlette.testclient import TestClient

from seatkit.errors import RecipeError
from seatkit.serve.app import MAX_JSON_DEPTH, MAX_JSON_DIGITS, MAX_JSON_LIST, MAX_JSON_STRING, create_app, parse_json
from seatkit.serve.designer import MAX_EXCLUDE, MAX_REFINERS, Designer

FAST = "/api/design?files=0&baseline=0&evaluate=0&view=0"


@pytest.fixture(scope="module")
def designer(tmp_path_factory):
    return Designer(tmp_path_factory.mktemp("serve-abuse"))


@pytest.fixture(scope="module")
def client(designer):
    with TestClient(create_app(designer)) as c:
        yield c


def _refused(r, *words, status=422):
    assert r.status_code == status, r.text
    message = r.json()["error"]
    assert "\n" not in message and "Traceback" not in message, message
    for w in words:
        assert w in message, message
    return message


# ---------------------------------------------------------------- base: files
def test_a_pose_base_outside_the_servers_folders_is_never_opened(client, designer, tmp_path):
    secret = tmp_path / "secret.yaml"
    secret.write_text("topsecret_key: qz7k9wvx\n")
    missing = tmp_path / "secrex.yaml"  # the same length: the messages differ only by the name
    answers = []
    for base in (str(secret), str(missing), "../../../" + str(secret).lstrip("/"), "../designs/x.yaml"):
        doc = f"base: {base}\njoints:\n  RightLeg: {{x: 80}}\n"
        r = client.post("/api/upload", params={"filename": "p.yaml"}, content=doc.encode())
        message = _refused(r, "base:", "outside the folders")
        assert "topsecret" not in message and "qz7k9wvx" not in message
        answers.append(message.replace("secrex", "secret"))
    # no existence oracle: the same answer for a file that exists and one that does not
    assert answers[0] == answers[1]


def test_a_pose_base_inside_the_servers_folders_is_read(client, designer):
    first = client.post("/api/upload", params={"filename": "a.yaml"}, content=b"base: upright-sitting\njoints:\n  RightLeg: {x: 70}\n")
    assert first.status_code == 200, first.text
    name = first.json()["pose"]
    second = client.post("/api/upload", params={"filename": "b.yaml"}, content=f"base: {name}\njoints:\n  LeftLeg: {{x: 70}}\n".encode())
    assert second.status_code == 200, second.text
    angles = client.get("/api/pose", params={"pose": second.json()["pose"]}).json()["angles"]
    from seatkit.skeleton import SEGMENT_INDEX

    assert angles[SEGMENT_INDEX["RightLeg"]][0] == pytest.approx(70) and angles[SEGMENT_INDEX["LeftLeg"]][0] == pytest.approx(70)


def test_the_loader_refuses_before_opening(tmp_path, monkeypatch):
    """The restriction is the loader's: a base outside ``base_roots`` is refused before its file is read."""
    from seatkit.body import poses

    outside = tmp_path / "outside"
    inside = tmp_path / "inside"
    outside.mkdir()
    inside.mkdir()
    (outside / "other.yaml").write_text("joints: {RightLeg: {x: 10}}\n")
    pose = inside / "pose.yaml"
    pose.write_text("base: ../outside/other.yaml\n")
    read = []
    real = poses._compose
    monkeypatch.setattr(poses, "_compose", lambda path: read.append(path.name) or real(path))
    assert poses.load_pose_file(pose).angles.any()  # without roots: read (the command line's behaviour)
    assert read == ["pose.yaml", "other.yaml"]
    read.clear()
    with pytest.raises(RecipeError, match="outside the folders"):
        poses.load_pose_file(pose, base_roots=[inside])
    assert read == ["pose.yaml"]


# ---------------------------------------------------------------- JSON caps
@pytest.mark.parametrize(
    ("body", "field", "words"),
    [
        (b"[" * 100_000, "request body", "nested"),
        (json.dumps({"template_params": {"steps": {"border": {"a": [[[[[[[[[[1]]]]]]]]]]}}}}).encode(), "template_params.steps.border.a", "nested"),
        (b'{"bodies": [{"params": {"mass": ' + b"9" * 5000 + b"}}]}", "bodies[0].params.mass", "number"),
        (b'{"seed": 1' + b"0" * 4400 + b"}", "seed", "number"),
        (json.dumps({"refiners": ["optimize"] * 10_000}).encode(), "refiners", "list"),
        (json.dumps({"pressure": {"exclude": ["Hips"] * 30_000}}).encode(), "pressure.exclude", "list"),
        (json.dumps({"bodies": [{"pose": "x" * 10_000}]}).encode(), "bodies[0].pose", "string"),
        (json.dumps({"x" * 10_000: 1}).encode(), "request body", "key"),
        (b'{"seed": NaN}', "request body", "NaN"),
    ],
)
def test_json_caps_name_the_field(client, designer, body, field, words):
    before = designer._latest
    r = client.post(FAST, content=body, headers={"Content-Type": "application/json"})
    message = _refused(r, words)
    assert message.startswith(field + ":"), message
    assert designer._latest == before  # refused: no sequence number taken


@pytest.mark.parametrize("text", ['"' + '\\"' * 120_000, '"\\' * 120_000, '{"a\\":' * 40_000])
def test_json_that_never_closes_a_string_is_refused(text):
    """Strings whose quotes are all escaped: the depth scan reads each character once (a scan restarting at every
    quote would read about 10^10 characters here, minutes of CPU, for one request under the size cap)."""
    with pytest.raises(RecipeError, match="not valid JSON"):
        parse_json(text.encode())


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=400) | st.text(alphabet='[]{}":,0123456789.eE-+ aNtrufl\\', max_size=400).map(str.encode))
def test_fuzz_json_is_a_value_or_one_line(data):
    try:
        parse_json(data)
    except RecipeError as e:
        assert "\n" not in str(e)


def test_the_caps_leave_every_real_request_through():
    recipe = {
        "template": "bench",
        "bodies": [{"model": "p5-female", "pose": "upright-sitting", "params": {"mass": 51.3}}] * 3,
        "template_params": {"steps": {"border": {"margin": 0.06}}},
        "refiners": [{"name": "optimize", "params": {}}, "catmull-clark-fit"],
    }
    assert parse_json(json.dumps(recipe).encode()) == recipe
    angles = {"angles": [[0.123456789012345678, -90.0, 1e-7]] * 21, "translation": [0, 0.9, 0]}
    assert parse_json(json.dumps(angles).encode()) == angles
    assert MAX_JSON_DEPTH >= 6 and MAX_JSON_LIST >= 21 and MAX_JSON_STRING >= 255 and MAX_JSON_DIGITS >= 25


# ---------------------------------------------------------------- sequence numbers
@pytest.mark.parametrize("seq", ["²", "١", "+1", "-1", "1.0", " 1", "9" * 5000, ""])
def test_sequence_numbers_are_plain_digits(client, seq):
    d = client.post(FAST, json={}).json()
    for route in ("evaluate", "baseline"):
        _refused(client.post(f"/api/design/{d['id']}/{route}", params={"seq": seq}), "seq")
    _refused(client.get("/api/pose", params={"pose": "upright-sitting", "frame": seq}), "frame")


# ---------------------------------------------------------------- supersession
def test_a_refused_request_never_cancels_the_running_design(client, designer):
    recipe = designer.prepare({"bodies": [{"model": "p50-male"}]})
    seq = designer.new_request()
    out: dict = {}

    def run():
        try:
            out["design"] = designer.design(recipe, seq)
        except Exception as e:  # noqa: BLE001  the test reports what stopped it
            out["error"] = e

    worker = threading.Thread(target=run)
    worker.start()
    for bad in ({"template": "no-such-template"}, {"bodies": [{"pose": "/etc/passwd"}]}, {"refiners": ["optimize"] * (MAX_REFINERS + 1)}):
        assert client.post(FAST, json=bad).status_code == 422
    assert client.post(FAST, content=b"[" * 1000, headers={"Content-Type": "application/json"}).status_code == 422
    worker.join()
    assert "error" not in out, out.get("error")
    assert out["design"].seq == seq


# ---------------------------------------------------------------- work per request
def test_work_per_request_is_bounded(client):
    _refused(client.post(FAST, json={"refiners": ["optimize"] * (MAX_REFINERS + 1)}), "refiners", f"at most {MAX_REFINERS}")
    _refused(client.post(FAST, json={"evaluate": {"baseline_refiners": ["optimize"] * (MAX_REFINERS + 1)}}), "baseline_refiners")
    _refused(client.post(FAST, json={"pressure": {"exclude": ["Hips"] * (MAX_EXCLUDE + 1)}}), "pressure.exclude")
    _refused(client.post(FAST, json={"template": "chair", "bodies": [{}, {}]}), "bodies", "at most 1")


def test_names_in_the_query_and_headers_are_capped(client, designer):
    before = designer._latest
    _refused(client.post("/api/upload", params={"filename": "x" * 5000 + ".yaml"}, content=b"joints: {}\n"), "filename")
    _refused(client.post(FAST, json={}, headers={"X-Request-Id": "r" * 5000}), "X-Request-Id")
    assert designer._latest == before


def test_errors_in_the_body_for_the_page(client):
    """``?errors=200``: the same error JSON with its status, answered 200 (a browser logs no failed load)."""
    r = client.post(FAST + "&errors=200", json={"template": "no-such-template"})
    assert r.status_code == 200 and r.json()["status"] == 422 and "no-such-template" in r.json()["error"]
    r = client.get("/api/preview", params={"request": "nobody", "errors": "200"})
    assert r.status_code == 200 and r.json()["status"] == 404
    assert client.get("/api/preview", params={"request": "nobody"}).status_code == 404


# ---------------------------------------------------------------- uploads
def test_uploads_are_evicted_least_recently_used(tmp_path):
    d = Designer(tmp_path / "serve")
    made = []
    for i in range(6):
        angles = [[0.0, 0.0, 0.0]] * 21
        angles = [row[:] for row in angles]
        angles[2][0] = float(i)
        made.append(d.make_pose(angles)["pose"])
    size = (d.uploads / made[0]).stat().st_size
    d.max_uploads_bytes = 3 * size + size // 2
    import os
    import time

    for k, name in enumerate(made):  # distinct use times, the first made used last
        t = time.time() - 100 + k
        os.utime(d.uploads / name, (t, t))
    d.prepare({"bodies": [{"pose": made[0]}]})  # a design asks for the oldest: it is used now
    angles[2][0] = 99.0
    newest = d.make_pose(angles)["pose"]
    left = {p.name for p in d.uploads.iterdir()}
    assert sum((d.uploads / n).stat().st_size for n in left) <= d.max_uploads_bytes
    assert newest in left and made[0] in left and made[5] in left
    assert made[1] not in left and made[2] not in left


def test_memory_is_bounded(tmp_path):
    """The designs kept are the most recently used, at most ``keep_designs``; the other caches have their own bounds."""
    from seatkit.geometry import skin
    from seatkit.subdivision import catmull_clark

    d = Designer(tmp_path / "serve")
    d.keep_designs = 2
    ids = []
    for model in ("p5-female", "p50-male", "p95-male"):
        design = d.design(d.prepare({"bodies": [{"model": model}]}), d.new_request())
        ids.append(design.id)
    assert d.cache_report()["designs_in_memory"] == 2 and d.cache_report()["designs_kept_at_most"] == 2
    assert d.get(ids[0]) is None and d.get(ids[2]) is not None
    # a dropped design's files leave the disk with it (they could no longer be served)
    d.files(d.get(ids[2]))
    assert (d.designs_dir / ids[2]).is_dir() and (d.recipes_dir / ids[2] / "recipe.zip").is_file()
    for model in ("default-female", "default-male"):
        d.design(d.prepare({"bodies": [{"model": model}]}), d.new_request())
    assert not (d.designs_dir / ids[2]).exists() and not (d.recipes_dir / ids[2]).exists()
    assert skin._CACHE.maxsize <= 16 and catmull_clark._OPS_CACHE.maxsize <= 64
    assert all(m._keep <= 8 for m in d.registry._bodies.values())
