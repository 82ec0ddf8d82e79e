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
    GET  /api/status                  the running stage, its request id and preview, the caches
    GET  /api/preview?request=ID      what the running design has made so far (posed bodies, the template's cage)
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
from pathlib import Path

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from seatkit.errors import SeatkitError, UnsupportedPoseError
from seatkit.serve.designer import MAX_UPLOAD_BYTES, Designer, Superseded, UploadError

STATIC = Path(__file__).resolve().parent / "static"

#: Largest JSON request body (a recipe, a pose's angles), bytes.
MAX_JSON_BYTES = 256 * 1024


def _error(e: Exception) -> JSONResponse:
    if isinstance(e, Superseded):
        return JSONResponse({"error": str(e), "kind": "superseded"}, status_code=409)
    if isinstance(e, UnsupportedPoseError):
        return JSONResponse({"error": str(e), "kind": "unsupported", "parts": list(e.parts)}, status_code=422)
    if isinstance(e, UploadError):
        return JSONResponse({"error": str(e), "kind": "upload"}, status_code=413 if "limit is" in str(e) else 422)
    return JSONResponse({"error": str(e), "kind": type(e).__name__}, status_code=422)


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


async def _json(request: Request):
    data = await _read_body(request, MAX_JSON_BYTES, "request body")
    if not data.strip():
        return None
    try:
        return json.loads(data)
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise SeatkitError(f"request body: not valid JSON ({e})") from None


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
                return _error(e)

        return endpoint

    async def index(request: Request):
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    async def options(request: Request):
        return JSONResponse(await run_in_threadpool(designer.options))

    async def get_pose(request: Request):
        q = request.query_params
        try:
            frame = int(q.get("frame", 0))
        except ValueError:
            raise SeatkitError(f"frame: expected a frame number, got {q.get('frame')!r}") from None
        try:
            params = json.loads(q.get("params") or "{}")
        except json.JSONDecodeError:
            raise SeatkitError("params: expected a JSON object of body parameters") from None
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
        data = await _read_body(request, MAX_UPLOAD_BYTES, f"upload {filename!r}")
        return JSONResponse(await run_in_threadpool(designer.upload, filename, data))

    async def design(request: Request):
        data = await _json(request)
        seq = designer.new_request()
        recipe = await run_in_threadpool(designer.prepare, data)
        request_id = request.headers.get("x-request-id") or request.query_params.get("request")
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
        return int(seq) if seq and seq.isdigit() else None

    async def evaluate(request: Request):
        d = _design_of(request)
        await run_in_threadpool(designer.evaluate, d, _seq(request))
        answer = designer.report(d)
        if _flag(request, "view", False):
            answer["view"] = designer.view(d)
        return JSONResponse(answer)

    async def baseline(request: Request):
        d = _design_of(request)
        seq = request.query_params.get("seq")
        await run_in_threadpool(designer.baseline, d, int(seq) if seq and seq.isdigit() else None)
        return JSONResponse(designer.report(d))

    async def files(request: Request):
        d = _design_of(request)
        await run_in_threadpool(designer.files, d)
        return JSONResponse(designer.report(d))

    async def view(request: Request):
        return JSONResponse(designer.view(_design_of(request)))

    async def preview(request: Request):
        answer = await run_in_threadpool(designer.preview, request.query_params.get("request", ""))
        if answer is None:
            raise HTTPException(404, "no preview of that request (not running, or nothing made yet)")
        return JSONResponse(answer)

    async def status(request: Request):
        return JSONResponse({**designer.status, "caches": designer.cache_report()})

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
        Route("/api/status", status),
        Route("/api/preview", guarded(preview)),
        Route("/files/{ident:str}/{name:str}", serve_file),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    app = Starlette(routes=routes, exception_handlers={HTTPException: not_found})
    app.state.designer = designer
    return app

