"""The web app's design service: validation, caches, one design at a time, supersession.

:class:`Designer` is what ``seatkit serve`` keeps warm between requests. It
validates a recipe with the CLI's own code (:func:`seatkit.recipe.load_recipe`,
:func:`seatkit.recipe.check_recipe`), confines every file it names to the
server's upload folder, and runs the design through
:func:`seatkit.pipeline.build` with nothing written and the evaluation
deferred, so that the first answer holds only what the page shows:

1. the design: bodies -> pressure -> template -> refiners -> limit surface
   (``build(write=False, processes=False)``, evaluation off);
2. the evaluation of our design (contact pressure on the designed surface,
   the Table 1 figures) with :func:`seatkit.pipeline.evaluate_result`, in
   the same request or (``evaluate=False``, as the page asks) in the next
   one (:meth:`Designer.evaluate`), so the design is shown before it;
3. only when asked: the flat-patch baseline (:meth:`Designer.baseline`) and
   the files (:meth:`Designer.files`: the recipe's exporters, written by
   :func:`seatkit.pipeline.write_result` exactly as ``seatkit build`` does,
   plus ``recipe.zip``, which rebuilds the design with
   ``seatkit build --recipe recipe.yaml``).

What stays warm (see :meth:`Designer.cache_report`): the plugin registry (built
once), the rest-pose rigs (:class:`_CachingRegistry`), the subdivision
operators of each cage topology (:mod:`seatkit.subdivision` keeps them per
topology), the templates (parsed once, by the registry), the imports, and the
designs themselves by recipe (moving a slider back shows the earlier design
at once).

Supersession: every design request takes a sequence number. Designs run
one at a time under a lock; a request that is no longer the newest when it
gets the lock, at the start of any stage of its build (the pipeline's
``progress`` callback) or between the surface fit's iterations
(:func:`seatkit.stopping.checkpoint`), stops with :class:`Superseded`, so a
newer request never waits for a stale one to finish and a stale result is
never returned as the newest. The flat-patch baseline the page asks for
when the sliders rest stops the same way.
"""

from __future__ import annotations

import copy
import hashlib
import io
import json
import threading
import time
import zipfile
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from seatkit.errors import RecipeError, SeatkitError
from seatkit.io import atomic_path, write_bytes_atomic, write_text_atomic

#: Largest upload (a BVH capture, a pose YAML), bytes.
MAX_UPLOAD_BYTES = 4 * 1024 * 1024

#: Suffixes an upload may have.
UPLOAD_SUFFIXES = (".bvh", ".yaml", ".yml")

#: Designs kept in memory (by recipe), with their results: a design holds
#: its posed bodies, pressures, cages and surface, about 10-15 MB for a chair.
KEEP_DESIGNS = 12

#: Total size of the upload folder (uploaded poses, poses made with the
#: sliders); beyond it the least recently used are deleted, bytes.
MAX_UPLOADS_BYTES = 64 * 1024 * 1024

#: Most refiners a recipe may list (each is a full pass over the cage).
MAX_REFINERS = 8

#: Most names a recipe's ``pressure.exclude`` may list.
MAX_EXCLUDE = 64

#: Longest a status request with ``since`` waits for a change, s.
STATUS_WAIT = 5.0

#: The slider joints: (key, label, segment, axis, sign). The slider shows
#: ``sign * angle`` in degrees, so that flexion is positive on both sides.
#: ``trunk-recline`` is the root's rotation about X (tilting the whole body
#: back about the hips); moving it keeps the thighs where they are (the hip
#: flexion sliders take the difference, see the page's script).
SLIDERS: tuple[tuple[str, str, str, int, int], ...] = (
    ("trunk-recline", "Trunk recline (behind vertical)", "Hips", 0, -1),
    ("hip-right", "Hip flexion, right", "RightUpLeg", 0, -1),
    ("hip-left", "Hip flexion, left", "LeftUpLeg", 0, -1),
    ("knee-right", "Knee flexion, right", "RightLeg", 0, 1),
    ("knee-left", "Knee flexion, left", "LeftLeg", 0, 1),
    ("shoulder-right", "Shoulder flexion, right", "RightArm", 0, -1),
    ("shoulder-left", "Shoulder flexion, left", "LeftArm", 0, -1),
    ("elbow-right", "Elbow flexion, right", "RightForeArm", 1, 1),
    ("elbow-left", "Elbow flexion, left", "LeftForeArm", 1, -1),
)


class Superseded(SeatkitError):
    """A newer design request arrived; this one stopped without a result."""


class UploadError(SeatkitError):
    """An upload is too large, has the wrong suffix or is not a readable pose."""


class _CachingBodyModel:
    """A body model whose rest-pose rigs are kept by parameters (posing is cheap, loading is not)."""

    def __init__(self, model, keep: int = 8):
        self._model = model
        self.name = model.name
        self.description = model.description
        self._rigs: OrderedDict[str, Any] = OrderedDict()
        self._keep = keep
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def __getattr__(self, name):  # params_schema and anything else the model declares
        return getattr(self._model, name)

    def make_body(self, *, params):
        key = json.dumps(params, sort_keys=True, default=str)
        with self._lock:
            rig = self._rigs.get(key)
            if rig is not None:
                self._rigs.move_to_end(key)
                self.hits += 1
                return rig
        rig = self._model.make_body(params=params)
        with self._lock:
            self.misses += 1
            self._rigs[key] = rig
            while len(self._rigs) > self._keep:
                self._rigs.popitem(last=False)
        return rig

    def pose(self, rig, pose, *, ground: bool = True):
        return self._model.pose(rig, pose, ground=ground)


class _ObservedTemplate:
    """A template that hands its inputs (the posed bodies, their pressure) and its cage to the designer's previews.

    These are the previews the page draws while a design is made: the body
    in its new pose, then the template's cage. The refined cages are not
    offered: after the refiners the design itself is a few milliseconds
    away, and the optimised cage looks like the template's.
    """

    def __init__(self, template, observe):
        self._template = template
        self._observe = observe
        self.name = template.name
        self.description = template.description

    def __getattr__(self, name):  # spec, params_schema, ...
        return getattr(self._template, name)

    def fit(self, bodies, pressures, *, params=None, seed=0):
        return next(self.fits(bodies, pressures, params=params, seed=seed))

    def fits(self, bodies, pressures, *, params=None, seed=0):
        """The template's cages (``seatkit.search.template_cages``), each shown as the template preview when it is made."""
        from seatkit.side import beside
        from seatkit.search import template_cages

        self._observe("posed", bodies=bodies, pressures=pressures)
        # what the cage check and the surface fit derive from the new bodies
        # alone, made beside the template fit (on the side thread, where it runs)
        beside(_prepare_bodies, bodies)
        for mesh in template_cages(self._template, bodies, pressures, params=params, seed=seed):
            self._observe("template", mesh=mesh)
            yield mesh


def _prepare_bodies(bodies) -> None:
    """Before they are asked for: what the template's checks derive from each body (kept per
    body, seatkit.template.checks), then its skin distance (kept by its arrays,
    seatkit.geometry.skin), which the surface fit asks for later."""
    from seatkit.geometry.skin import SkinDistance
    from seatkit.template.checks import prepare_body

    for body in bodies:
        prepare_body(body)
    for body in bodies:
        SkinDistance.of(body.vertices, body.faces).prepare()


class _CachingRegistry:
    """The plugin registry as the server uses it.

    Each body model is wrapped by :class:`_CachingBodyModel` (rigs kept);
    templates by :class:`_ObservedTemplate`, which reports to ``observe``
    what it made (it ignores them outside a design, e.g. for the baseline).
    Everything else is the registry's own.
    """

    def __init__(self, registry, observe=None):
        self._registry = registry
        self._bodies = {name: _CachingBodyModel(c) for name, c, _ in registry.items("body_model")}
        observe = observe or (lambda stage, **parts: None)
        self._wrapped = {("template", n): _ObservedTemplate(c, observe) for n, c, _ in registry.items("template")}

    def get(self, kind: str, name: str):
        if kind == "body_model" and name in self._bodies:
            return self._bodies[name]
        if (kind, name) in self._wrapped:
            return self._wrapped[(kind, name)]
        return self._registry.get(kind, name)

    def __getattr__(self, name):  # names, items, plugin_of
        return getattr(self._registry, name)


class _Plugins:
    """What :func:`seatkit.pipeline.build` needs of a plugin manager: its registry."""

    def __init__(self, registry):
        self.registry = registry


@dataclass
class Design:
    """One computed design and what has been derived from it so far."""

    id: str
    seq: int
    recipe: dict
    result: Any
    seconds: dict = field(default_factory=dict)
    evaluated: bool = False
    baseline: dict | None = None
    files: dict | None = None
    people: list | None = None  # who it is for (:meth:`Designer._people`), read once
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _b64(array, dtype) -> str:
    import base64

    return base64.b64encode(np.ascontiguousarray(array, dtype=dtype).tobytes()).decode("ascii")


def _triangles(faces) -> np.ndarray:
    """Quads (or triangles) as triangles, for the view."""
    faces = np.asarray(faces)
    if faces.shape[1] == 3:
        return faces
    return np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])


class Designer:
    """The warm state of ``seatkit serve``; thread-safe.

    Parameters
    ----------
    root : Path
        The server's folder: ``uploads/`` (poses the page uploads or makes
        with the sliders), ``designs/ID/`` (the files of a design, written when
        asked), ``recipes/ID/`` (``recipe.zip``). Only files in these folders
        are ever served.
    pm : SeatkitPluginManager, optional
        Default: a fresh one.
    """

    def __init__(self, root: Path, pm=None):
        from seatkit.plugins import get_plugin_manager

        self.root = Path(root).resolve()
        self.uploads = self.root / "uploads"
        self.designs_dir = self.root / "designs"
        self.recipes_dir = self.root / "recipes"
        for d in (self.uploads, self.designs_dir, self.recipes_dir):
            d.mkdir(parents=True, exist_ok=True)
        self.pm = pm if pm is not None else get_plugin_manager()
        self.registry = _CachingRegistry(self.pm.registry, observe=self._observe)
        self._plugins = _Plugins(self.registry)
        self._run = threading.Lock()  # one design (or baseline, or export) at a time
        self._state = threading.Lock()
        self._latest = 0
        self._designs: OrderedDict[str, Design] = OrderedDict()
        self.status: dict = {"seq": 0, "stage": "idle", "started": None, "version": 0}  # version: +1 at each change (:meth:`status_after`)
        self._observing: tuple[int, str] | None = None  # (seq, request id) of the running design
        self._preview: dict = {}
        self._waiters: list = []  # (event loop, asyncio.Event) of the status requests waiting for a change
        self.hits = 0  # designs answered from memory
        self.max_uploads_bytes = MAX_UPLOADS_BYTES
        self.keep_designs = KEEP_DESIGNS

    # ---------------------------------------------------------------- options
    def options(self) -> dict:
        """What the page offers: poses, body models and their parameters, templates and theirs, the sliders."""
        from seatkit.body import list_poses
        from seatkit.recipe import DEFAULT_BODY_MODEL, DEFAULT_POSE

        bodies = []
        for name, model, plugin in self.registry.items("body_model"):
            if name == "file":
                continue  # needs a file on the server: not offered on the page
            if not getattr(model, "available", lambda: True)():
                continue  # an optional model whose libraries are not installed
            params = _body_params(model) or self._own_mass(name)
            bodies.append({"name": name, "description": model.description, "plugin": plugin, "params": params})
        templates = []
        for name, template, plugin in self.registry.items("template"):
            people = getattr(getattr(template, "spec", None), "people", None) or (1, 1)
            templates.append(
                {
                    "name": name,
                    "description": template.description,
                    "plugin": plugin,
                    "params": _template_params(template, self.registry),
                    "people": [int(people[0]), int(people[1])],
                }
            )
        return {
            "poses": [{"name": p.name, "description": p.description, "supported": p.supported} for p in list_poses()],
            "default_pose": DEFAULT_POSE,
            "bodies": bodies,
            "default_body": DEFAULT_BODY_MODEL,
            "templates": templates,
            "default_template": "chair",
            "sliders": [{"key": k, "label": lab, "segment": seg, "axis": ax, "sign": s} for k, lab, seg, ax, s in SLIDERS],
            "max_upload_bytes": MAX_UPLOAD_BYTES,
        }

    def _own_mass(self, name: str) -> list[dict]:
        """A body model that declares no parameters: its mass, as its rest body has it."""
        try:
            mass = float(self.registry.get("body_model", name).make_body(params={}).mass)
        except (SeatkitError, AttributeError, TypeError, ValueError):
            return []
        return [{"key": "mass", "label": "mass", "unit": "kg", "default": mass, "minimum": 20, "maximum": 300, "description": "body mass"}]

    # ------------------------------------------------------------------ poses
    def upload(self, filename: str, data: bytes) -> dict:
        """Keep an uploaded BVH or pose YAML (after reading it) and return its name in the upload folder."""
        suffix = Path(filename or "").suffix.lower()
        if suffix not in UPLOAD_SUFFIXES:
            msg = f"upload {filename!r}: expected a .bvh or a pose .yaml file"
            raise UploadError(msg)
        if len(data) > MAX_UPLOAD_BYTES:
            msg = f"upload {filename!r}: {len(data)} bytes; the limit is {MAX_UPLOAD_BYTES} bytes"
            raise UploadError(msg)
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as e:
            msg = f"upload {filename!r}: not UTF-8 text (byte {e.start}); BVH and pose YAML files are text"
            raise UploadError(msg) from None
        name = f"upload-{_digest(data)}{'.yaml' if suffix == '.yml' else suffix}"
        path = self.uploads / name
        if not path.exists():
            # a temporary name of its own (two requests may send the same file at once), with the same
            # suffix: the loaders go by it; renamed onto the final name only once it reads as a pose
            try:
                with atomic_path(path) as tmp:
                    tmp.write_bytes(data)
                    self._read_pose(tmp)
            except SeatkitError as e:  # the loader's message, naming the file the user sent and no folder of the server
                text = str(e).replace(str(tmp.resolve()), Path(filename).name).replace(str(tmp), Path(filename).name)
                raise UploadError(text.replace(str(self.uploads) + "/", "")) from None
        self._used(path)
        return {"pose": name, "original": Path(filename).name}

    def _read_pose(self, path: Path) -> None:
        """Read a pose file the way a build will (an error is the loader's own message); a ``base:`` only from :meth:`pose_roots`."""
        from seatkit.body import load_pose
        from seatkit.body.poses import load_pose_file
        from seatkit.recipe import DEFAULT_BODY_MODEL

        if path.suffix.lower() == ".bvh":
            rig = self.registry.get("body_model", DEFAULT_BODY_MODEL).make_body(params={})
            load_pose(str(path), rig=rig)
        else:
            load_pose_file(path, base_roots=self.pose_roots())

    def pose_roots(self) -> list[Path]:
        """The folders a pose file's ``base:`` may name a file in: the pose library, the plugins' pose folders, the uploads."""
        from seatkit.body.poses import pose_dirs

        return [Path(d) for d, _ in pose_dirs(getattr(self.registry, "pose_dirs", None))] + [self.uploads]

    def pose_angles(self, pose: str, *, frame: int = 0, model: str | None = None, params: Mapping | None = None) -> dict:
        """A pose as the sliders start from it: intrinsic XYZ Euler angles per segment (degrees).

        A BVH pose is retargeted onto the body it will be used with, so the
        angles depend on ``model`` and ``params``.
        """
        from scipy.spatial.transform import Rotation

        from seatkit.body import load_pose
        from seatkit.body.poses import EULER_ORDER, find_pose, load_pose_file
        from seatkit.recipe import DEFAULT_BODY_MODEL, looks_like_path
        from seatkit.skeleton import SEGMENTS

        spec = self.confine_pose(pose, "pose")
        if looks_like_path(spec) and Path(spec).suffix.lower() == ".bvh":
            rig = self.registry.get("body_model", model or DEFAULT_BODY_MODEL).make_body(params=dict(params or {}))
            p = load_pose(spec, frame=frame, rig=rig)
            angles = Rotation.from_rotvec(p.rotations).as_euler(EULER_ORDER, degrees=True)
            translation, supported, description = p.translation, None, f"frame {frame} of {Path(spec).name}"
        else:
            ps = load_pose_file(spec if looks_like_path(spec) else find_pose(spec), base_roots=self.pose_roots())
            angles, translation, supported, description = ps.angles, ps.root_translation, ps.supported, ps.description
        return {
            "pose": pose,
            "segments": list(SEGMENTS),
            "angles": np.round(np.asarray(angles, dtype=float), 6).tolist(),
            "translation": np.asarray(translation, dtype=float).tolist(),
            "supported": supported,
            "description": description,
        }

    def make_pose(self, angles, translation=(0.0, 0.0, 0.0), *, description: str = "") -> dict:
        """Write a pose YAML (every joint) into the upload folder; its name is its content's hash."""
        from seatkit.skeleton import N_SEGMENTS, SEGMENTS

        def numbers(value, shape, what):
            ok = isinstance(value, (list, tuple)) and all(
                isinstance(row, (list, tuple)) and len(row) == shape[-1] and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in row)
                for row in (value if len(shape) == 2 else [value])
            )
            array = np.asarray(value, dtype=float) if ok else None
            if array is None or array.shape != shape or not np.isfinite(array).all():
                raise RecipeError(what)
            return array

        a = numbers(angles, (N_SEGMENTS, 3), f"angles: expected {N_SEGMENTS} rows of 3 finite angles in degrees (x, y, z per segment, {', '.join(SEGMENTS)})")
        t = numbers(translation, (3,), "translation: expected [x, y, z] in metres (finite numbers)")
        doc = {
            "description": description or "made with seatkit serve",
            "root": {"rotation": dict(zip("xyz", map(float, a[0]))), "translation": [float(v) for v in t]},
            "joints": {SEGMENTS[i]: dict(zip("xyz", map(float, a[i]))) for i in range(1, N_SEGMENTS)},
        }
        text = yaml.dump(doc, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper), sort_keys=False)  # libyaml's emitter: the same text, a third of the time
        name = f"pose-{_digest(text.encode())}.yaml"
        path = self.uploads / name
        if not path.exists():  # two requests may make the same pose at once: each writes its own temporary file
            write_text_atomic(path, text)
        self._used(path)
        return {"pose": name}

    def _used(self, path: Path, *, new: bool = True) -> None:
        """Mark an upload as just used; after a new one, delete the least recently used beyond :data:`MAX_UPLOADS_BYTES`.

        The poses of the designs in memory are kept (their files and
        ``recipe.zip`` read them).
        """
        import os

        try:
            os.utime(path)
        except OSError:
            return
        if not new:
            return
        with self._state:
            keep = {Path(b["pose"]).name for d in self._designs.values() for b in d.recipe["bodies"]}
        keep.add(path.name)
        files = []
        for f in self.uploads.iterdir():
            if f.name.startswith("."):
                continue  # a file being written
            try:
                st = f.stat()
            except OSError:
                continue
            files.append((st.st_mtime, st.st_size, f))
        total = sum(size for _, size, _ in files)
        for _, size, f in sorted(files, key=lambda x: x[0]):
            if total <= self.max_uploads_bytes:
                break
            if f.name in keep:
                continue
            f.unlink(missing_ok=True)
            total -= size

    def confine_pose(self, spec: str, where: str) -> str:
        """A pose argument from a request: a library name, or a file in the upload folder (resolved)."""
        from seatkit.recipe import looks_like_path

        if not isinstance(spec, str) or not looks_like_path(spec):
            return spec
        path = (self.uploads / spec).resolve()
        if Path(spec).is_absolute() or path.parent != self.uploads:
            msg = (
                f"{where}: {spec!r}: the server reads pose files only from its upload folder; "
                "upload the file (POST /api/upload) and give the name it returns"
            )
            raise RecipeError(msg)
        return str(path)

    # ----------------------------------------------------------------- recipe
    def prepare(self, data: Any) -> dict:
        """Validate a request's recipe with the CLI's code; return it normalised, confined and with the server's output folder.

        Raises
        ------
        RecipeError
            The CLI's message for the same recipe (without the file and line
            a YAML file has).
        """
        from seatkit.pipeline import recipe_id
        from seatkit.recipe import check_recipe, load_recipe, looks_like_path

        if data is None:
            data = {}
        if not isinstance(data, Mapping):
            raise RecipeError(f"<recipe>: a recipe must be a mapping of keys (template, bodies, ...), got {type(data).__name__}")
        recipe, document = load_recipe(data)
        for key, entries in (("refiners", recipe["refiners"]), ("evaluate.baseline_refiners", recipe["evaluate"]["baseline_refiners"])):
            if len(entries) > MAX_REFINERS:
                raise RecipeError(f"{key}: {len(entries)} refiners; the web app runs at most {MAX_REFINERS}")
        exclude = recipe["pressure"].get("exclude") or []
        if len(exclude) > MAX_EXCLUDE:
            raise RecipeError(f"pressure.exclude: {len(exclude)} names; the web app takes at most {MAX_EXCLUDE}")
        for i, body in enumerate(recipe["bodies"]):
            body["pose"] = self.confine_pose(body["pose"], f"bodies[{i}].pose")
            if "path" in body["params"]:
                msg = f"bodies[{i}].params.path: the web app does not read body files; use a registered body model"
                raise RecipeError(msg)
        recipe["output"] = None
        check_recipe(recipe, self.registry, document=document)
        template = self.registry.get("template", recipe["template"])
        most = (getattr(getattr(template, "spec", None), "people", None) or (1, 8))[1]
        if len(recipe["bodies"]) > most:
            raise RecipeError(f"bodies: {len(recipe['bodies'])} people; template {recipe['template']!r} seats at most {most}")
        for body in recipe["bodies"]:
            # a parameter given at the model's own value is the same body: the same recipe, the same design
            own = {p["key"]: p["default"] for p in _body_params(self.registry.get("body_model", body["model"])) if p.get("default") is not None}
            body["params"] = {k: v for k, v in body["params"].items() if not (k in own and v == own[k])}
            if looks_like_path(body["pose"]):
                self._used(Path(body["pose"]), new=False)
        ident = recipe_id(recipe)
        recipe["output"] = str(self.designs_dir / ident)
        return recipe

    # ----------------------------------------------------------------- design
    def new_request(self) -> int:
        """A sequence number for a design request; it supersedes every earlier one."""
        with self._state:
            self._latest += 1
            return self._latest

    def _check(self, seq: int, stage: str, *, report: bool = True) -> None:
        """Stop (:class:`Superseded`) unless ``seq`` is the newest request; else show ``stage`` in the status."""
        with self._state:
            if seq < self._latest:
                raise Superseded(f"superseded by a newer request (stopped before {stage})")
            if not report:
                return
            same = self.status.get("seq") == seq
            self._publish({
                "seq": seq,
                "request": self._observing[1] if self._observing and self._observing[0] == seq else None,
                "stage": stage,
                "started": self.status.get("started") if same else time.time(),
                "preview": self._preview.get("stage") if self._preview.get("seq") == seq else None,
            })

    def _observe(self, stage: str, **parts) -> None:
        """Keep what a stage of the running design made, for :meth:`preview`."""
        with self._state:
            if self._observing is None:
                return
            seq, request = self._observing
            if self._preview.get("seq") != seq:
                self._preview = {"seq": seq, "request": request}
            self._preview.update(parts, stage=stage)
            self._publish({**self.status, "preview": stage})

    def preview(self, request: str, *, bodies: bool = True) -> dict | None:
        """What the running (or last) design of ``request`` has made so far, as :meth:`view` draws it; None if nothing yet.

        After the pressure (stage ``posed``): the posed bodies, coloured by
        their importance (the pressure supported everywhere); after the
        template (stage ``template``): the same bodies, the template's cage
        and its limit surface at the recipe's level. Each is made from the
        objects the running design made, when asked (a few milliseconds).
        With ``bodies=False`` the bodies are left out (``None``): the page
        asks so for the template's preview once it has drawn the posed
        bodies of the same request, which are the same.
        """
        from seatkit.subdivision import limit_surface

        with self._state:
            p = dict(self._preview)
        if not request or p.get("request") != request or "bodies" not in p:
            return None
        views = [self._body_view(b, f.pressure, "importance") for b, f in zip(p["bodies"], p["pressures"])] if bodies else None
        out = {"seq": p["seq"], "stage": p["stage"], "bodies": views, "surface": None, "cage": None}
        mesh = p.get("mesh")
        if mesh is not None:
            level = p.get("level", 3)
            out["surface"] = self._surface_view(limit_surface(mesh, level=level))
            out["cage"] = self._cage_view(mesh)
        return out

    def _idle(self, seq: int) -> None:
        with self._state:
            if self.status.get("seq") == seq:
                self._publish({"seq": seq, "stage": "idle", "started": None})

    def _publish(self, status: dict) -> None:
        """Set the status (the caller holds ``_state``), one version on, and wake the requests waiting for a change."""
        self.status = {**status, "version": self.status["version"] + 1}
        for loop, event in self._waiters:
            try:
                loop.call_soon_threadsafe(event.set)
            except RuntimeError:  # its event loop has closed: nobody is waiting there any more
                pass

    async def status_after(self, version: int | None, wait: float | None = None) -> dict:
        """The status once its ``version`` differs from ``version`` (at once without one), or after ``wait`` seconds as it is.

        The page asks for the status while a design runs: answered when
        something changes (a stage starts, a preview is made, the design
        ends) rather than asked again and again. ``wait`` defaults to
        :data:`STATUS_WAIT`. A waiting request costs nothing until then: the
        design's thread wakes it (``call_soon_threadsafe``).
        """
        import asyncio

        waiter = (asyncio.get_running_loop(), asyncio.Event())
        with self._state:
            if version is None or self.status["version"] != version:
                return self.status
            self._waiters.append(waiter)
        try:
            await asyncio.wait_for(waiter[1].wait(), STATUS_WAIT if wait is None else wait)
        except asyncio.TimeoutError:
            pass
        finally:
            with self._state:
                self._waiters.remove(waiter)
        return self.status

    def design(self, recipe: dict, seq: int, request: str | None = None, *, evaluate: bool = True) -> Design:
        """Compute a design (or return it from memory): the view's part only.

        With ``evaluate=False`` the evaluation (the contact pressure on the
        designed surface, our Table 1 figures) is left for
        :meth:`evaluate`: the page shows the design as soon as it exists
        and the figures follow.

        Raises
        ------
        Superseded
            A newer request arrived before or while this one ran.
        SeatkitError
            The build's own errors (an unsupported pose, an infeasible support).
        """
        from seatkit.pipeline import build
        from seatkit.stopping import stoppable

        ident = Path(recipe["output"]).name
        with self._state:
            hit = self._designs.get(ident)
        if hit is not None:
            self._check(seq, "done", report=False)
            self.hits += 1
            with self._state:
                self._designs.move_to_end(ident)
            return hit
        with self._run:
            with self._state:
                self._observing = (seq, request or f"seq-{seq}")
                self._preview = {"seq": seq, "request": self._observing[1], "level": recipe["surface_level"]}
            self._check(seq, "start")
            try:
                start = time.perf_counter()
                fast = copy.deepcopy(recipe)
                fast["evaluate"]["enabled"] = False
                with stoppable(lambda: self._check(seq, "its next iteration", report=False)):
                    result = build(fast, pm=self._plugins, progress=lambda s: self._check(seq, s), write=False, processes=False)
                designed = time.perf_counter()
                result.recipe = recipe
                seconds = {"design": designed - start}
                design = Design(ident, seq, recipe, result, seconds)
                if evaluate:
                    self._evaluate(design, seq)
            finally:
                with self._state:
                    self._observing = None
                self._idle(seq)
        dropped = []
        with self._state:
            self._designs[ident] = design
            while len(self._designs) > self.keep_designs:
                dropped.append(self._designs.popitem(last=False)[0])
        if dropped:
            import shutil

            with self._run:  # not while a design's files are being written
                for old in dropped:  # its files can no longer be served: they leave the disk too
                    if old in self._designs:
                        continue
                    shutil.rmtree(self.designs_dir / old, ignore_errors=True)
                    shutil.rmtree(self.recipes_dir / old, ignore_errors=True)
        return design

    def _evaluate(self, design: Design, seq: int | None) -> None:
        """Our evaluation of a design (the caller holds the run lock); the baseline is :meth:`baseline`'s."""
        from seatkit.pipeline import evaluate_result
        from seatkit.stages import StageTimer

        result = design.result
        if not design.recipe["evaluate"]["enabled"] or design.evaluated:
            design.evaluated = True
            return
        check = (lambda s: self._check(seq, s)) if seq is not None else (lambda s: None)
        check("evaluate")
        start = time.perf_counter()
        result.recipe = copy.deepcopy(design.recipe)
        result.recipe["evaluate"]["baseline"] = None
        try:
            evaluate_result(result, self.registry, StageTimer(check))
        finally:
            result.recipe = design.recipe
        design.seconds["evaluate"] = time.perf_counter() - start
        design.evaluated = True

    def evaluate(self, design: Design, seq: int | None = None) -> None:
        """Evaluate a design made with ``evaluate=False`` (once): the contact pressure and our Table 1 figures.

        With ``seq`` (the ``request_seq`` of the design's answer), stops
        (:class:`Superseded`) when a newer design request has arrived: the
        page asks for the figures after showing a design, and a newer slider
        move comes first.
        """
        with design.lock:
            if design.evaluated:
                return
            with self._run:
                try:
                    self._evaluate(design, seq)
                finally:
                    if seq is not None:
                        self._idle(seq)

    def get(self, ident: str) -> Design | None:
        with self._state:
            return self._designs.get(ident)

    def baseline(self, design: Design, seq: int | None = None) -> dict | None:
        """Fit and evaluate the recipe's baseline (default flat-patch) for a design, once; ``None`` without one.

        With ``seq``, stops (:class:`Superseded`) when a newer design request
        has arrived, before it starts or while it runs (at the start of each
        of its parts and between the surface fit's iterations): the page asks
        for the baseline when the sliders rest, and a slider move made
        meanwhile comes first, without waiting for the baseline to finish.
        """
        from contextlib import nullcontext

        from seatkit.evaluate import design_segments
        from seatkit.pipeline import fit_baseline
        from seatkit.stages import StageTimer
        from seatkit.stopping import stoppable

        ev = design.recipe["evaluate"]
        if not (ev["enabled"] and ev["baseline"]):
            return None
        self.evaluate(design, seq)  # ours first: the baseline's figures go beside them
        with design.lock:
            if design.baseline is not None:
                return design.baseline
            with self._run:
                if seq is not None:
                    self._check(seq, "baseline")
                try:
                    result = design.result
                    progress = (lambda s: self._check(seq, s)) if seq is not None else None
                    stop = stoppable(lambda: self._check(seq, "the baseline's next iteration", report=False)) if seq is not None else nullcontext()
                    with stop:
                        base = fit_baseline(
                            design.recipe, result.bodies, result.pressures, self.registry, design_segments(result.initial_mesh), StageTimer(progress)
                        )
                finally:
                    if seq is not None:
                        self._idle(seq)
            result.timings["baseline (parallel)"] = base.seconds
            result.metrics["baseline_template"] = ev["baseline"]
            result.metrics["baseline"] = base.metrics
            result.baseline = base
            design.seconds["baseline"] = base.seconds
            design.baseline = base.metrics
            return design.baseline

    def files(self, design: Design) -> dict:
        """Write a design's files (the recipe's exporters, report.json, recipe.zip) once; role -> file name."""
        from seatkit.pipeline import write_result

        self.evaluate(design)
        self.baseline(design)
        with design.lock:
            if design.files is not None:
                return design.files
            with self._run:
                start = time.perf_counter()
                write_result(design.result, self.registry)
                files = {role: Path(p).name for role, p in design.result.files.items()}
                self._write_recipe(design)
                design.seconds["files"] = time.perf_counter() - start
            design.files = files
            return files

    def _write_recipe(self, design: Design) -> None:
        """``recipes/ID/recipe.yaml`` (+ the pose files it names) and ``recipe.zip`` of them."""
        from seatkit.io import jsonable
        from seatkit.recipe import looks_like_path

        recipe = jsonable(copy.deepcopy(design.recipe))
        recipe.pop("output")
        if recipe["pressure"].get("exclude") is None:
            recipe["pressure"].pop("exclude", None)
        folder = self.recipes_dir / design.id
        folder.mkdir(parents=True, exist_ok=True)
        members: dict[str, bytes] = {}
        for body in recipe["bodies"]:
            if looks_like_path(body["pose"]):
                src = Path(body["pose"])
                members[src.name] = src.read_bytes()
                body["pose"] = src.name  # beside recipe.yaml
        text = (
            "# made by seatkit serve; rebuild with: seatkit build --recipe recipe.yaml\n"
            + yaml.safe_dump(recipe, sort_keys=False)
        )
        members = {"recipe.yaml": text.encode(), **members}
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as z:
            for name, data in members.items():
                z.writestr(f"seatkit-design/{name}", data)
        for name, data in {**members, "recipe.zip": buffer.getvalue()}.items():
            write_bytes_atomic(folder / name, data)

    # ---------------------------------------------------------------- answers
    def file_path(self, ident: str, name: str) -> Path | None:
        """The path of a design's file, or None unless it is one the server wrote for that design."""
        design = self.get(ident)
        if design is None or design.files is None:
            return None
        if name in design.files.values() and "/" not in name and "\\" not in name:
            folder = self.designs_dir / ident
        elif name in ("recipe.zip", "recipe.yaml"):
            folder = self.recipes_dir / ident
        else:
            return None
        path = (folder / name).resolve()
        if path.parent != folder.resolve() or not path.is_file():
            return None
        return path

    def report(self, design: Design) -> dict:
        """The JSON answer for a design: metrics, timings, file URLs (once written)."""
        from seatkit.evaluate import TABLE_COLUMNS
        from seatkit.io import jsonable

        r = design.result
        files = None
        if design.files is not None:
            names = dict(design.files)
            names["recipe_zip"] = "recipe.zip"
            names["recipe_yaml"] = "recipe.yaml"
            files = {role: f"/files/{design.id}/{name}" for role, name in names.items()}
        return jsonable(
            {
                "id": design.id,
                "seq": design.seq,
                "template": design.recipe["template"],
                "people": self._people(design) if design.people is None else design.people,
                "control_mesh": {"vertices": len(r.control_mesh.vertices), "faces": len(r.control_mesh.faces)},
                "special_cases": r.control_mesh.meta.get("special_cases", []),
                "evaluated": design.evaluated,
                "metrics": r.metrics,
                "table_columns": [{"key": k, "label": lab, "unit": u, "scale": s} for k, lab, u, s in TABLE_COLUMNS],
                "timings_s": r.timings,
                "seconds": design.seconds,
                "files": files,
            }
        )

    def _people(self, design: Design) -> list[dict]:
        """Who the design is for, person by person in seat order: model, pose, and the mass and height used."""
        from seatkit.recipe import looks_like_path

        out = []
        for entry, body in zip(design.recipe["bodies"], design.result.bodies):
            own = {p["key"]: p["default"] for p in _body_params(self.registry.get("body_model", entry["model"]))}
            used = {k: v for k, v in {**own, **entry["params"]}.items() if v is not None}
            pose = entry["pose"]
            label = pose
            if looks_like_path(pose):
                label = Path(pose).name
                if Path(pose).suffix.lower() != ".bvh":
                    try:
                        label = str(yaml.safe_load(Path(pose).read_text()).get("description") or label)
                    except (OSError, yaml.YAMLError, AttributeError):
                        pass
            out.append(
                {
                    "model": entry["model"],
                    "pose": label,
                    "mass_kg": float(body.mass),
                    "height_m": used.get("height", used.get("stature")),
                    "params": used,
                }
            )
        design.people = out
        return out

    @staticmethod
    def _body_view(body, pressure, kind: str) -> dict:
        return {
            "name": body.name,
            "positions": _b64(body.vertices, "<f4"),
            "faces": _b64(_triangles(body.faces), "<u4"),
            "pressure": _b64(pressure, "<f4"),
            "pressure_kind": kind,
            "max_pressure_pa": float(np.max(pressure)),
        }

    @staticmethod
    def _surface_view(s) -> dict:
        return {"positions": _b64(s.vertices, "<f4"), "normals": _b64(s.normals, "<f4"), "faces": _b64(_triangles(s.faces), "<u4")}

    @staticmethod
    def _cage_view(cage) -> dict:
        edges = {tuple(sorted((int(f[i]), int(f[(i + 1) % len(f)])))) for f in cage.faces for i in range(len(f))}
        return {"positions": _b64(cage.vertices, "<f4"), "edges": _b64(np.array(sorted(edges)), "<u4")}

    def view(self, design: Design) -> dict:
        """The meshes the page draws: bodies (with contact pressure), the limit surface and the cage (float32/uint32, base64)."""
        r = design.result
        contact = r.contact_pressures or [None] * len(r.bodies)
        bodies = [
            self._body_view(body, f.pressure, "contact") if f is not None else self._body_view(body, imp.pressure, "importance")
            for body, imp, f in zip(r.bodies, r.pressures, contact)
        ]
        points = np.concatenate([r.surface.vertices] + [b.vertices for b in r.bodies])
        return {
            "id": design.id,
            "seq": design.seq,
            "stage": "done",
            "bounds": [points.min(axis=0).tolist(), points.max(axis=0).tolist()],
            "bodies": bodies,
            "surface": self._surface_view(r.surface),
            "cage": self._cage_view(r.control_mesh),
        }

    def cache_report(self) -> dict:
        """What is warm, for the benchmark and ``GET /api/status``."""
        from seatkit.subdivision import catmull_clark

        rigs = {name: {"hits": m.hits, "misses": m.misses} for name, m in self.registry._bodies.items() if m.hits or m.misses}
        return {
            "registry": "built once at start",
            "rigs": rigs,
            "subdivision_operators": len(catmull_clark._OPS_CACHE),
            "designs_in_memory": len(self._designs),
            "designs_kept_at_most": self.keep_designs,
            "uploads_bytes_at_most": self.max_uploads_bytes,
            "design_hits": self.hits,
        }


def _body_params(model) -> list[dict]:
    """A model's parameters for the page, from its ``params_schema`` (JSON schema), defaults its own values; [] without one."""
    schema = getattr(model, "params_schema", None)
    if not (isinstance(schema, Mapping) and isinstance(schema.get("properties"), Mapping)):
        return []
    out = []
    for key, prop in schema["properties"].items():
        common = {"key": key, "label": prop.get("title", key), "default": prop.get("default"), "description": prop.get("description", ""), "advanced": bool(prop.get("advanced", False))}
        if prop.get("type") in ("number", "integer"):
            out.append({**common, "unit": prop.get("unit", ""), "minimum": prop.get("minimum"), "maximum": prop.get("maximum")})
        elif "enum" in prop:
            out.append({**common, "enum": list(prop["enum"])})
    return out


#: The template step options offered as a designer's controls (the rest are behind the page's
#: "advanced" fold): (step, option, label). Each is a declared option of the step (its unit and
#: range are the step's), set as a recipe sets it: ``template_params: {steps: {STEP: {OPTION: value}}}``.
DESIGNER_OPTIONS: tuple[tuple[str, str, str, bool], ...] = (
    ("seat", "height", "seat height (under the ischia, above the floor)", False),
    ("seat", "backrest_height", "backrest height (its top above the seat)", False),
    ("seat", "depth", "seat depth (back of the buttocks to the front edge)", False),
    ("seat", "recline", "backrest recline (behind vertical)", False),
    ("outer-columns", "margin", "seat and back: width beyond the body", False),
    ("border", "width", "seat edge: surface beyond the body", False),
    ("border", "margin", "base: margin of the ground rectangle", False),
    ("clearance", "sink", "softness: deepest sink into the surface", False),
    ("armrests", "min_load_fraction", "armrests: share of the load an arm must carry", True),
    ("no-backrest", "min_load_fraction", "backrest: share of the load below which there is none", True),
)
"""The template options the page offers (step, option, label, behind the *advanced* fold): a designer's dimensions first, the algorithm's thresholds folded away."""

#: What a blank designer option means (the field's placeholder).
BLANK_MEANS = {("seat", "height"): "from the pose", ("seat", "backrest_height"): "from the fit", ("seat", "depth"): "to the knee", ("seat", "recline"): "from the pose"}


def _designer_options(spec, registry) -> list[dict]:
    """The :data:`DESIGNER_OPTIONS` a YAML template has (a step it runs once), with the template's values as defaults."""
    out = []
    names = [entry.get("step") for entry in spec.steps]
    for step, key, label, advanced in DESIGNER_OPTIONS:
        if names.count(step) != 1:
            continue
        try:
            declared = registry.get("template_step", step).options[key]
        except (SeatkitError, KeyError, AttributeError):
            continue
        entry = spec.steps[names.index(step)]
        out.append(
            {
                "key": f"steps.{entry.get('label', step)}.{key}",
                "label": label,
                "unit": declared.unit,
                "default": entry.get(key, declared.default),
                "minimum": declared.minimum,
                "maximum": declared.maximum,
                "description": f"{declared.description} (template_params: steps: {entry.get('label', step)}: {key})",
                "placeholder": BLANK_MEANS.get((step, key), "the template's") if entry.get(key, declared.default) is None else None,
                "advanced": advanced,
            }
        )
    return out


def _template_params(template, registry=None) -> list[dict]:
    """A template's parameters for the page, from its own declaration: a YAML template's designer options and ``parameters``, or a ``params_schema``."""
    spec = getattr(template, "spec", None)
    if spec is not None and hasattr(spec, "parameters"):
        from seatkit.template.schema import PARAMETERS

        designer = _designer_options(spec, registry) if registry is not None else []
        return designer + [
            {"key": k, "label": k, "unit": unit, "default": spec.parameters.get(k, default), "minimum": 0, "maximum": None, "description": meaning, "advanced": True}
            for k, (default, unit, meaning) in PARAMETERS.items()
        ]
    schema = getattr(template, "params_schema", None)
    if isinstance(schema, Mapping):
        return _body_params(type("T", (), {"params_schema": schema})())
    return []
