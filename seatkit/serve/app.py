"""The Starlette app of ``seatkit serve``: the page, its static files and the JSON API.

The API (docs/serve.md describes every route)::

    GET  /api/options                 poses, body models, templates and their parameters, sliders
    GET  /api/pose?pose=NAME          a pose's joint angles (degrees), where the sliders start
    POST /api/pose                    {"angles": [[x, y, z] x 21], "translation": [x, y, z]} -> {"pose": FILE}
    POST /api/upload?filename=F.bvh   the file as the body -> {"pose": FILE}
    POST /api/design                  a recipe (JSON) -> the report and file URLs
    POST /api/design/ID/evaluate      our evaluation of a design made with ?evaluate=0 -> the report
    POST /api/design/ID/baseline      the flat-patch baseline of a design -> the report
    POST /api/design/ID/files         write the design's files -> the report with file URLs
    GET  /api/design/ID/view          the meshes the page draws
    GET  /api/status[?since=VERSION]  the running stage, its request id and preview, the caches (once changed)
    GET  /api/preview?request=ID      what the running design has made so far (posed bodies, the template's cage; bodies=0: without the bodies)
    GET  /files/ID/NAME               a file the server wrote for design ID (else 404)

Errors are JSON ``{"error": message, "kind": ...}``: a bad recipe, pose or
upload is 422 with the message the CLI prints for it; an unsupported pose is
422 with ``kind: "unsupported"`` and the body parts; a request superseded by
a newer one is 409. The blocking work runs on worker threads
(:func:`starlette.concurrency.run_in_threadpool`), so the server answers
status polls while a design runs.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from seatkit.errors import RecipeError, SeatkitError, UnsupportedPoseError
from seatkit.serve.designer import MAX_UPLOAD_BYTES, Designer, Superseded, UploadError

STATIC = Path(__file__).resolve().parent / "static"

#: Largest JSON request body (a recipe, a pose's angles), bytes.
MAX_JSON_BYTES = 256 * 1024
#: Deepest nesting of a JSON request (a recipe's deepest key, ``template_params.steps.STEP.OPTION``, is 4 deep).
MAX_JSON_DEPTH = 12
#: Longest list in a JSON request (the pose angles are 21 rows; a bench has a few people).
MAX_JSON_LIST = 64
#: Longest string in a JSON request (a name, a pose file, a description), characters.
MAX_JSON_STRING = 512
#: Most digits of a number in a JSON request (a float64 needs 17).
MAX_JSON_DIGITS = 40

#: Strings (a key with its colon) and brackets; an unterminated string runs to the end of the text, so
#: no match is tried twice over the same characters (linear time on any input).
_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*(?:"(?:\s*:)?)?|[\[\]{}]', re.DOTALL)


def _error(e: Exception) -> JSONResponse:
    if isinstance(e, Superseded):
        return JSONResponse({"error": str(e), "kind": "superseded"}, status_code=409)
    if isinstance(e, UnsupportedPoseError):
        return JSONResponse({"error": str(e), "kind": "unsupported", "parts": list(e.parts)}, status_code=422)
    if isinstance(e, UploadError):
        return JSONResponse({"error": str(e), "kind": "upload"}, status_code=413 if "limit is" in str(e) else 422)
    return JSONResponse({"error": str(e), "kind": type(e).__name__}, status_code=422)


def _in_body(request: Request, response: JSONResponse) -> JSONResponse:
    """With ``?errors=200`` (the page's requests), an error answer as 200 with its status in the JSON.

    A browser logs every non-2xx answer as a console error; a refusal or a
    superseded request is an expected answer to the page, which reads
    ``status`` and ``kind`` instead.
    """
    if request.query_params.get("errors") != "200":
        return response
    data = json.loads(response.body)
    return JSONResponse({**data, "status": response.status_code}, status_code=200)


async def _read_body(request: Request, limit: int, what: str) -> bytes:
    """The request body, refused (413) beyond ``limit`` bytes without reading the rest."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise UploadError(f"{what}: {declared} bytes; the limit is {limit} bytes")
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise UploadError(f"{what}: more than {limit} bytes; the limit is {limit} bytes")
        chunks.append(chunk)
    return b"".join(chunks)


def _field(path: tuple) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "request body"


class _LongNumber(int):
    """A number too long to convert: its length, refused by :func:`_check_shape` with its field."""


def _number(text: str):
    if len(text) > MAX_JSON_DIGITS:
        return _LongNumber(len(text))
    return float(text) if any(c in text for c in ".eE") else int(text)


def _check_shape(value, path: tuple = ()) -> None:
    """Every list at most MAX_JSON_LIST items, every string and key at most MAX_JSON_STRING characters."""
    if isinstance(value, _LongNumber):
        raise RecipeError(f"{_field(path)}: a number of {int(value)} characters; at most {MAX_JSON_DIGITS} are accepted")
    if isinstance(value, str):
        if len(value) > MAX_JSON_STRING:
            raise RecipeError(f"{_field(path)}: a string of {len(value)} characters; at most {MAX_JSON_STRING} are accepted")
    elif isinstance(value, list):
        if len(value) > MAX_JSON_LIST:
            raise RecipeError(f"{_field(path)}: a list of {len(value)} items; at most {MAX_JSON_LIST} are accepted")
        for i, v in enumerate(value):
            _check_shape(v, path + (i,))
    elif isinstance(value, dict):
        if len(value) > MAX_JSON_LIST:
            raise RecipeError(f"{_field(path)}: {len(value)} keys; at most {MAX_JSON_LIST} are accepted")
        for k, v in value.items():
            if len(k) > MAX_JSON_STRING:
                raise RecipeError(f"{_field(path)}: a key of {len(k)} characters; at most {MAX_JSON_STRING} are accepted")
            _check_shape(v, path + (k,))


def parse_json(data: bytes):
    """A request's JSON, refused (:class:`RecipeError`, naming the field) beyond the caps above; None when empty.

    The nesting depth is counted on the text before it is parsed (a deeply
    nested document never reaches the parser's recursion); a number's
    digits are counted as the parser meets it (Python refuses to convert an
    integer of more than 4,300 digits, with an error, not a 422).
    """
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise RecipeError(f"request body: not UTF-8 text (byte {e.start})") from None
    if not text.strip():
        return None
    stack: list = []  # the key (or "[]") each open bracket was met under
    key = None
    for m in _TOKENS.finditer(text):
        t = m.group()
        if t[0] == '"':
            key = t if t.endswith(":") and len(t) > 1 else None
        elif t in "[{":
            stack.append(json.loads(key.rstrip(": \t\r\n")) if key else 0)
            key = None
            if len(stack) > MAX_JSON_DEPTH:
                path = tuple(k for k in stack[:-1] if k != 0) or ()
                raise RecipeError(f"{_field(path)}: nested more than {MAX_JSON_DEPTH} levels deep; at most {MAX_JSON_DEPTH} are accepted")
        else:
            if stack:
                stack.pop()
            key = None
    try:
        value = json.loads(text, parse_int=_number, parse_float=_number, parse_constant=_no_constant)
    except (json.JSONDecodeError, RecursionError) as e:
        raise RecipeError(f"request body: not valid JSON ({e})") from None
    _check_shape(value)
    return value


def _no_constant(name: str):
    raise RecipeError(f"request body: {name} is not a number JSON allows")


async def _json(request: Request):
    return parse_json(await _read_body(request, MAX_JSON_BYTES, "request body"))


def _count(text: str, name: str, what: str) -> int:
    """A whole number from a query parameter: ASCII digits only (not "²", "١", "+1" or 5,000 digits)."""
    if not re.fullmatch(r"[0-9]{1,9}", text):
        shown = text if len(text) <= 20 else text[:20] + "..."
        raise RecipeError(f"{name}: expected {what} (digits 0-9), got {shown!r}")
    return int(text)


def _flag(request: Request, name: str, default: bool) -> bool:
    value = request.query_params.get(name)
    if value is None:
        return default
    return value.lower() not in ("0", "false", "no", "")


def create_app(designer: Designer) -> Starlette:
    """The app around a :class:`~seatkit.serve.designer.Designer` (its state is the designer's)."""

    def guarded(handler):
        async def endpoint(request: Request):
            try:
                return await handler(request)
            except SeatkitError as e:
                return _in_body(request, _error(e))
            except HTTPException as e:
                if request.query_params.get("errors") != "200":
                    raise
                return _in_body(request, JSONResponse({"error": e.detail, "kind": "not-found"}, status_code=e.status_code))

        return endpoint

    async def index(request: Request):
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    async def options(request: Request):
        return JSONResponse(await run_in_threadpool(designer.options))

    async def get_pose(request: Request):
        q = request.query_params
        frame = _count(q.get("frame", "0"), "frame", "a frame number")
        params = parse_json((q.get("params") or "{}").encode())
        if not isinstance(params, dict):
            raise SeatkitError("params: expected a JSON object of body parameters")
        pose = q.get("pose") or ""
        answer = await run_in_threadpool(designer.pose_angles, pose, frame=frame, model=q.get("model"), params=params)
        return JSONResponse(answer)

    async def post_pose(request: Request):
        data = await _json(request)
        if not isinstance(data, dict) or "angles" not in data:
            raise SeatkitError('request body: expected {"angles": [[x, y, z], ...21 rows], "translation": [x, y, z]}')
        answer = await run_in_threadpool(
            designer.make_pose, data["angles"], data.get("translation", (0.0, 0.0, 0.0)), description=str(data.get("description", ""))
        )
        return JSONResponse(answer)

    async def upload(request: Request):
        filename = request.query_params.get("filename", "")
        if len(filename) > MAX_JSON_STRING:
            raise RecipeError(f"filename: {len(filename)} characters; at most {MAX_JSON_STRING} are accepted")
        data = await _read_body(request, MAX_UPLOAD_BYTES, f"upload {filename!r}")
        return JSONResponse(await run_in_threadpool(designer.upload, filename, data))

    async def design(request: Request):
        request_id = request.headers.get("x-request-id") or request.query_params.get("request")
        if request_id is not None and len(request_id) > 100:
            raise RecipeError(f"X-Request-Id: {len(request_id)} characters; at most 100 are accepted")
        data = await _json(request)
        recipe = await run_in_threadpool(designer.prepare, data)
        seq = designer.new_request()  # only a valid request supersedes the running design
        evaluate = _flag(request, "evaluate", True)
        d = await run_in_threadpool(lambda: designer.design(recipe, seq, request_id, evaluate=evaluate))
        if evaluate or _flag(request, "baseline", True) or _flag(request, "files", True):
            await run_in_threadpool(designer.evaluate, d, seq)  # a design from memory may not be evaluated yet
        if _flag(request, "baseline", True):
            await run_in_threadpool(designer.baseline, d, seq)
        if _flag(request, "files", True):
            await run_in_threadpool(designer.files, d)
        answer = designer.report(d)
        answer["request_seq"] = seq  # this request's number (a design from memory keeps the seq it was made under)
        if _flag(request, "view", False):
            answer["view"] = designer.view(d)
        return JSONResponse(answer)

    def _design_of(request: Request):
        d = designer.get(request.path_params["ident"])
        if d is None:
            raise HTTPException(404, "no such design on this server (it may have been dropped from memory: design it again)")
        return d

    def _seq(request: Request) -> int | None:
        seq = request.query_params.get("seq")
        return None if seq is None else _count(seq, "seq", "the request_seq of a design's answer")

    async def evaluate(request: Request):
        d = _design_of(request)
        await run_in_threadpool(designer.evaluate, d, _seq(request))
        answer = designer.report(d)
        if _flag(request, "view", False):
            answer["view"] = designer.view(d)
        return JSONResponse(answer)

    async def baseline(request: Request):
        d = _design_of(request)
        await run_in_threadpool(designer.baseline, d, _seq(request))
        return JSONResponse(designer.report(d))

    async def files(request: Request):
        d = _design_of(request)
        await run_in_threadpool(designer.files, d)
        return JSONResponse(designer.report(d))

    async def view(request: Request):
        return JSONResponse(designer.view(_design_of(request)))

    async def preview(request: Request):
        answer = await run_in_threadpool(designer.preview, request.query_params.get("request", ""), bodies=_flag(request, "bodies", True))
        if answer is None:
            raise HTTPException(404, "no preview of that request (not running, or nothing made yet)")
        return JSONResponse(answer)

    async def status(request: Request):
        since = request.query_params.get("since")
        version = None if not since else _count(since, "since", "the version of a status answer")
        current = await designer.status_after(version)
        return JSONResponse({**current, "caches": designer.cache_report()})

    async def serve_file(request: Request):
        path = designer.file_path(request.path_params["ident"], request.path_params["name"])
        if path is None:
            raise HTTPException(404, "not a file of this server")
        return FileResponse(path, filename=path.name)

    async def not_found(request: Request, exc: HTTPException):
        return JSONResponse({"error": exc.detail, "kind": "not-found"}, status_code=exc.status_code)

    routes = [
        Route("/", index),
        Route("/api/options", guarded(options)),
        Route("/api/pose", guarded(get_pose), methods=["GET"]),
        Route("/api/pose", guarded(post_pose), methods=["POST"]),
        Route("/api/upload", guarded(upload), methods=["POST"]),
        Route("/api/design", guarded(design), methods=["POST"]),
        Route("/api/design/{ident:str}/evaluate", guarded(evaluate), methods=["POST"]),
        Route("/api/design/{ident:str}/baseline", guarded(baseline), methods=["POST"]),
        Route("/api/design/{ident:str}/files", guarded(files), methods=["POST"]),
        Route("/api/design/{ident:str}/view", guarded(view)),
        Route("/api/status", guarded(status)),
        Route("/api/preview", guarded(preview)),
        Route("/files/{ident:str}/{name:str}", serve_file),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    app = Starlette(routes=routes, exception_handlers={HTTPException: not_found})
    app.state.designer = designer
    return app

