"""Recipes: the YAML (or mapping) that says what one build does.

A recipe names every stage's component by its registered name and gives its
parameters::

    template: chair                 # a registered template
    template_params: {}             # overrides of the template's parameters
    bodies:                         # people in seat order (one for a chair)
      - model: default-male         # a registered body model
        params: {mass: 75}          # model parameters (mass in kg)
        pose: upright-sitting       # library name, pose YAML or BVH path
        frame: 0                    # BVH frame
        offset: [0, 0, 0]           # metres, optional placement
    pressure: {solver: qp, lambda: 0.013, mu: 0.5}
    refiners: [optimize, {name: catmull-clark-fit, params: {fairness: 0.1}}]
    exporters: [usd, obj, surface, body-ply]   # a name, or {name, params}
    surface_level: 3
    output: out/chair
    seed: 0
    export_frame: canonical         # or capture: geometry files in the capture's own frame

Instead of ``bodies``, ``sitters`` lists people who share one seat (one
design for all of them at the same place, :mod:`seatkit.sitters`): body
entries without ``offset``, or ``{population: ansur-ii, percentiles: [5,
50, 95], sexes: [f, m], pose: upright-sitting}`` for the survey's
boundary manikins. ``sitters: {shared: true}`` beside ``bodies`` says that
those bodies share one seat (how a written recipe, report.json and
design.npz record sitters).

:func:`load_recipe` validates the shape against :data:`RECIPE_SCHEMA`, fills
defaults, applies command-line overrides, then :func:`check_recipe` checks
that every named component, pose and file exists, before any geometry work.
Every error names the file, line and key path.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from seatkit.constants import (
    DEFAULT_BODY_MASS,
    DEFAULT_LAMBDA,
    DEFAULT_MU,
    DEFAULT_SEED,
    DEFAULT_SUPPORT_DISTANCE,
    LAMBDA_RANGE,
    MU_RANGE,
)
from seatkit.errors import ParamError, RecipeError
from seatkit.io import recipe_id  # noqa: F401  (recipe_id is part of this module's API; it lives beside jsonable)
from seatkit.messages import format_path, quote
from seatkit.options import check_options
from seatkit.yamlio import Document, load_yaml, validate

DEFAULT_REFINERS = ("optimize", "catmull-clark-fit")
DEFAULT_EXPORTERS = ("usd", "obj", "surface", "body-ply", "design", "report-png", "report-html")
DEFAULT_SURFACE_LEVEL = 3
DEFAULT_POSE = "upright-sitting"
DEFAULT_BODY_MODEL = "default-male"

_NAME = {"type": "string", "minLength": 1, "maxLength": 200, "pattern": "^[^\\x00]*$"}  # a component's name
_PATH = {"type": "string", "minLength": 1, "maxLength": 4096, "pattern": "^[^\\x00]*$"}  # a name or a file path
_PARAMS = {"type": "object"}

#: Physical range of every number of a recipe: (least, greatest, unit, what).
#: The YAML schema and :func:`check_recipe` (which sees command-line flags
#: too) both use it. Numbers are finite (``.nan``/``.inf`` are refused, see
#: :mod:`seatkit.yamlio`) except ``lambda``, whose ``inf`` means a rigid body.
LIMITS: dict[str, tuple[float, float, str, str]] = {
    "lambda": (*LAMBDA_RANGE, "", "a number from 1e-9 to 1e6, or inf"),
    "mu": (*MU_RANGE, "", "a friction coefficient between 0 and 10"),
    "support_distance": (1e-4, 0.5, "m", "a distance in metres from 0.0001 to 0.5"),
    "gap": (0.0, 10.0, "m", "a gap in metres between 0 and 10"),
    "offset": (-10.0, 10.0, "m", "coordinates in metres between -10 and 10"),
    "frame": (0, 10_000_000, "", "a frame number between 0 and 10000000"),
    "seed": (0, 2**32 - 1, "", "a whole number between 0 and 4294967295"),
    "surface_level": (1, 4, "", "a subdivision level from 1 to 4"),
}


def _ranged(key: str, kind: str = "number") -> dict:
    lo, hi, _, _ = LIMITS[key]
    return {"type": kind, "minimum": lo, "maximum": hi}


_NUMBER_OR_INF = {
    "anyOf": [_ranged("lambda"), {"const": math.inf}, {"type": "string", "enum": ["inf", "infinity"]}]
}

#: A refiner or exporter entry: a name, or ``{name, params}``.
_REFINER = {
    "anyOf": [
        _NAME,
        {
            "type": "object",
            "additionalProperties": False,
            "required": ["name"],
            "properties": {"name": _NAME, "params": _PARAMS},
        },
    ]
}

#: The most sitters one shared design takes (each is designed alone too, for the cost of sharing).
MAX_SITTERS = 12

#: Frames the geometry files can be written in: the design's (each person
#: facing +Z, centred; seatkit.body.frame) or the capture's own (one person).
EXPORT_FRAMES = ("canonical", "capture")

#: The baseline's refiners when the recipe names none: the Sit & Relax surface fit.
DEFAULT_BASELINE_REFINERS = ("catmull-clark-fit",)

RECIPE_SCHEMA: dict = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "template": _NAME,
        "template_params": _PARAMS,
        "bodies": {
            "type": "array",
            "minItems": 1,
            "items": {
                "type": "object",
                "additionalProperties": False,
                "properties": {
                    "model": _NAME,
                    "params": _PARAMS,
                    "pose": _PATH,
                    "frame": _ranged("frame", "integer"),
                    "offset": {"type": "array", "items": _ranged("offset"), "minItems": 3, "maxItems": 3},
                    "name": _NAME,
                },
            },
        },
        # people who share one seat (seatkit.sitters): a list of body entries (no offset: they sit at one place),
        # or a population's boundary manikins
        "sitters": {
            "type": ["array", "object"],
            "minItems": 1,
            "maxItems": MAX_SITTERS,
            "items": {
                "type": "object",
                "additionalProperties": False,
                "properties": {"model": _NAME, "params": _PARAMS, "pose": _PATH, "frame": _ranged("frame", "integer"), "name": _NAME},
            },
            "additionalProperties": False,
            "properties": {
                "shared": {"const": True},  # beside bodies: these bodies share one seat (how a written recipe records sitters)
                "population": {"enum": ["ansur-ii"]},
                "percentiles": {"type": "array", "minItems": 1, "items": {"enum": [5, 50, 95]}},
                "sexes": {"type": "array", "minItems": 1, "items": {"enum": ["f", "m", "female", "male"]}},
                "pose": _PATH,
                "frame": _ranged("frame", "integer"),
            },
        },
        "placement": {
            "type": "object",
            "additionalProperties": False,
            "properties": {"gap": _ranged("gap")},
        },
        "pressure": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "solver": _NAME,
                "lambda": _NUMBER_OR_INF,
                "mu": _ranged("mu"),
                "exclude": {"anyOf": [{"type": "array", "items": _NAME}, {"type": "null"}]},  # null: none
                "options": _PARAMS,
            },
        },
        "refiners": {"type": "array", "items": _REFINER},
        "exporters": {"type": "array", "items": _REFINER},
        # the params of exporters written as {name, params}, by name (how a loaded recipe keeps them)
        "exporter_params": {"type": "object", "additionalProperties": _PARAMS},
        "surface_level": _ranged("surface_level", "integer"),
        "evaluate": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "enabled": {"type": "boolean"},
                "baseline": {"anyOf": [_NAME, {"type": "null"}]},
                "baseline_refiners": {"type": "array", "items": _REFINER},
                "support_distance": _ranged("support_distance"),
                "interface_pressure": {"type": "boolean"},
            },
        },
        "output": {"anyOf": [_PATH, {"type": "null"}]},  # null: the default folder (seatkit.output.output_target)
        "seed": _ranged("seed", "integer"),
        "structure": {"type": "object"},  # checked against seatkit.structure.build.OPTIONS in load_recipe
        "export_frame": {"enum": list(EXPORT_FRAMES)},
    },
}


#: Keys of a recipe that are present only when it has them.
_OPTIONAL_KEYS = ("structure", "exporter_params", "export_frame", "sitters")


@dataclass(frozen=True, eq=False)
class Recipe(Mapping):
    """A validated recipe: what one build runs, every key present, every name checked.

    Made by :func:`check_recipe` (which :func:`seatkit.pipeline.build` calls
    on a mapping or a file; a Recipe given to ``build`` is used as it is,
    validated once). Its fields are the recipe's top-level keys, with the
    defaults of :func:`default_recipe` filled in; it also reads as the
    mapping it was made from (``recipe["pressure"]["lambda"]``), so
    components written against the mapping keep working. The fields cannot
    be reassigned; the sections are the validated plain data (dicts and
    lists, owned by the recipe: do not edit them). To change a recipe, edit
    :meth:`to_dict` (or pass it through :func:`apply_overrides`) and check it
    again. Equal to a mapping with the same keys and values.
    """

    template: str
    template_params: dict
    bodies: list
    placement: dict
    pressure: dict
    refiners: list
    exporters: list
    surface_level: int
    evaluate: dict
    output: str | None
    seed: int
    #: the ``structure`` section (seatkit.structure.build.settings), None when the recipe has none
    structure: dict | None = None
    #: ``{exporter name: params}`` of the exporters given as ``{name, params}``, None when none is
    exporter_params: dict | None = None
    #: ``capture`` to write the geometry files in the capture's own frame; None (the default) for the canonical frame
    export_frame: str | None = None
    #: ``{"shared": True}`` (and a population's keys) when ``bodies`` are sitters of one seat (:mod:`seatkit.sitters`), None for people side by side
    sitters: dict | None = None

    @classmethod
    def from_normalised(cls, data: Mapping) -> "Recipe":
        """A Recipe of normalised recipe data (:func:`load_recipe`'s), copied; not checked (see :func:`check_recipe`)."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            msg = f"recipe: unknown key {unknown[0]!r}; expected one of {', '.join(sorted(names))}"
            raise RecipeError(msg)
        return cls(**copy.deepcopy({k: v for k, v in data.items() if k in names}))

    def to_dict(self) -> dict:
        """The recipe as a new plain dict (a deep copy: edit it freely)."""
        return copy.deepcopy(dict(self))

    def __getitem__(self, key: str) -> Any:
        if key not in self._keys():
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return iter(self._keys())

    def __len__(self) -> int:
        return len(self._keys())

    def _keys(self) -> tuple[str, ...]:
        return tuple(f.name for f in fields(self) if f.name not in _OPTIONAL_KEYS or getattr(self, f.name) is not None)


def default_recipe() -> dict:
    """The recipe of ``seatkit build --template chair`` with nothing else given."""
    return {
        "template": "chair",
        "template_params": {},
        "bodies": [{"model": DEFAULT_BODY_MODEL, "params": {}, "pose": DEFAULT_POSE, "frame": 0}],
        "placement": {},
        "pressure": {"solver": "qp", "lambda": DEFAULT_LAMBDA, "mu": DEFAULT_MU, "exclude": None, "options": {}},
        "refiners": [{"name": n, "params": {}} for n in DEFAULT_REFINERS],
        "exporters": list(DEFAULT_EXPORTERS),
        "surface_level": DEFAULT_SURFACE_LEVEL,
        "evaluate": {
            "enabled": True,
            "baseline": "flat-patch",
            "baseline_refiners": [{"name": n, "params": {}} for n in DEFAULT_BASELINE_REFINERS],
            "support_distance": DEFAULT_SUPPORT_DISTANCE,
        },
        "output": None,
        "seed": DEFAULT_SEED,
    }


def _normalise(data: Mapping[str, Any], base_dir: Path | None) -> dict:
    """Fill defaults into validated recipe data; resolve relative paths."""
    recipe = default_recipe()
    for key in ("template", "surface_level", "output", "seed", "export_frame"):
        if key in data:
            recipe[key] = data[key]
    recipe["template_params"] = dict(data.get("template_params", {}))
    recipe["placement"] = dict(data.get("placement", {}))
    recipe["evaluate"].update(copy.deepcopy(data.get("evaluate", {})))
    recipe["evaluate"]["baseline_refiners"] = [_refiner_entry(r) for r in recipe["evaluate"]["baseline_refiners"]]
    people = data.get("bodies")
    if "sitters" in data:
        sitters = data["sitters"]
        recipe["sitters"] = {"shared": True}
        if not isinstance(sitters, Mapping):
            people = sitters
        elif "population" in sitters:  # a population's boundary manikins (seatkit.sitters)
            from seatkit.manikins import expand_population

            spec = {k: v for k, v in sitters.items() if k != "shared"}
            recipe["sitters"].update(copy.deepcopy(spec))
            if people is None:  # beside bodies (a written recipe), the bodies are the manikins already
                people = expand_population(spec, DEFAULT_POSE)
    if people is not None:
        recipe["bodies"] = []
        for body in people:
            entry = {"model": DEFAULT_BODY_MODEL, "params": {}, "pose": DEFAULT_POSE, "frame": 0}
            entry.update(copy.deepcopy(body))
            recipe["bodies"].append(entry)
    pressure = recipe["pressure"]
    pressure.update(copy.deepcopy(data.get("pressure", {})))
    if isinstance(pressure["lambda"], str):
        pressure["lambda"] = math.inf
    if "refiners" in data:
        recipe["refiners"] = [_refiner_entry(r) for r in data["refiners"]]
    params = copy.deepcopy(dict(data.get("exporter_params") or {}))
    if "exporters" in data:
        entries = [_refiner_entry(e) for e in data["exporters"]]
        recipe["exporters"] = [e["name"] for e in entries]
        params.update({e["name"]: e["params"] for e in entries if e["params"]})
    if params:
        recipe["exporter_params"] = params
    if "structure" in data:
        from seatkit.structure.build import enable, settings

        recipe["structure"] = settings(data["structure"])
        if recipe["structure"]["enabled"]:
            enable(recipe)
    if base_dir is not None:
        for body in recipe["bodies"]:
            body["pose"] = _resolve_path_like(body["pose"], base_dir)
            if isinstance(body["params"].get("path"), str):
                body["params"]["path"] = _resolved(base_dir, body["params"]["path"])
        if recipe["output"] is not None:
            recipe["output"] = str((base_dir / recipe["output"]).resolve())
    return recipe


def _refiner_entry(r) -> dict:
    return {"name": r, "params": {}} if isinstance(r, str) else {"name": r["name"], "params": dict(r.get("params", {}))}


def _is_file(path) -> bool:
    """Whether ``path`` is a file; False (not an exception) for a NUL byte or a name too long."""
    try:
        return Path(path).is_file()
    except (OSError, ValueError):
        return False


def _resolved(base_dir: Path, path: str) -> str:
    """``base_dir / path`` made absolute; as given if the OS refuses it (check_recipe reports it)."""
    try:
        return str((base_dir / path).resolve())
    except (OSError, ValueError):
        return path


def looks_like_path(spec: str) -> bool:
    """Whether a pose/body argument names a file rather than a library entry."""
    return "/" in spec or "\\" in spec or Path(spec).suffix.lower() in (".yaml", ".yml", ".bvh", ".npz", ".glb", ".gltf")


def _resolve_path_like(spec: str, base_dir: Path) -> str:
    if looks_like_path(spec) and not Path(spec).is_absolute():
        return _resolved(base_dir, spec)
    return spec


def load_recipe(source: str | Path | Mapping | None = None) -> tuple[dict, Document | None]:
    """Load and validate a recipe.

    Parameters
    ----------
    source : path, mapping or None
        A YAML file, an already-parsed mapping, or None for the defaults.

    Returns
    -------
    recipe : dict
        The normalised recipe (every key present).
    document : Document or None
        The parsed file, for locating later errors.

    Raises
    ------
    RecipeError
        With file, line, key path and what was expected.
    """
    if source is None:
        return default_recipe(), None
    if isinstance(source, Mapping):
        doc = Document(dict(source), "<recipe>")
        base_dir = None
    else:
        path = Path(source)
        doc = load_yaml(path)
        base_dir = path.resolve().parent
    if not isinstance(doc.data, dict):
        raise doc.error((), f"a recipe must be a mapping of keys (template, bodies, ...), got {type(doc.data).__name__}")
    validate(doc, RECIPE_SCHEMA)
    sitters = doc.data.get("sitters")
    marker = isinstance(sitters, dict) and sitters.get("shared") is True
    if sitters is not None and "bodies" in doc.data and not marker:
        raise doc.error(("sitters",), "give bodies (people side by side) or sitters (people who share one seat), not both; or sitters: {shared: true} beside bodies")
    if isinstance(sitters, dict) and "population" not in sitters and not (marker and "bodies" in doc.data):
        raise doc.error(("sitters",), "expected a list of sitters (body entries), {population: ansur-ii, ...}, or {shared: true} beside bodies")
    if isinstance(doc.data.get("structure"), dict):
        from seatkit.structure.build import OPTIONS as STRUCTURE_OPTIONS

        check_options("structure", STRUCTURE_OPTIONS, doc.data["structure"], fail=lambda path, message: doc.error(("structure", *path), message))
    return _normalise(doc.data, base_dir), doc


def parse_body_spec(spec: str) -> dict:
    """Turn a ``--body`` argument into a recipe body entry's model and params.

    ``default-male``, ``default-female``: a registered model name.
    ``NAME:key=value,key=value``: a model with parameters (numbers parsed).
    A path to a ``.npz`` or ``.glb``/``.gltf`` file: the ``file`` model.
    """
    if looks_like_path(spec) and ":" not in Path(spec).name:
        return {"model": "file", "params": {"path": str(Path(spec).resolve())}}
    name, _, rest = spec.partition(":")
    params: dict[str, Any] = {}
    if rest:
        for item in rest.split(","):
            key, eq, value = item.partition("=")
            if not eq or not key:
                msg = f"--body {spec!r}: expected NAME or NAME:key=value,...; cannot read {item!r}"
                raise RecipeError(msg)
            try:
                params[key.strip()] = float(value)
            except ValueError:
                params[key.strip()] = value.strip()
    return {"model": name, "params": params}


def parse_sitter_spec(spec: str) -> dict:
    """Turn a ``--sitter BODY:POSE`` argument into a recipe body entry (BODY as ``--body`` takes it; POSE after the last colon)."""
    body, colon, pose = spec.rpartition(":")
    if not colon or not body or not pose:
        msg = f"--sitter {spec!r}: expected BODY:POSE, e.g. p5-female:upright-sitting"
        raise RecipeError(msg)
    entry = parse_body_spec(body)
    return {**entry, "pose": pose, "frame": 0}


def apply_overrides(
    recipe: dict,
    *,
    template: str | None = None,
    poses: list[str] | None = None,
    bodies: list[str] | None = None,
    mass: float | None = None,
    frame: int | None = None,
    height: float | None = None,
    refiners: list[str] | None = None,
    exporters: list[str] | None = None,
    solver: str | None = None,
    lam: float | None = None,
    mu: float | None = None,
    output: str | None = None,
    seed: int | None = None,
    surface_level: int | None = None,
    evaluate: bool | None = None,
    baseline: str | None = None,
    export_frame: str | None = None,
    sitters: list[str] | None = None,
    options: list[str] | None = None,
) -> dict:
    """Return a copy of ``recipe`` (a normalised dict or a :class:`Recipe`) with command-line flags applied (flags win).

    ``poses`` and ``bodies`` are in seat order; a single ``--body`` applies
    to every pose, and vice versa. The copy is a plain dict, to check again
    (:func:`check_recipe`, or :func:`seatkit.pipeline.build` does).
    """
    r = recipe.to_dict() if isinstance(recipe, Recipe) else copy.deepcopy(recipe)
    if template is not None:
        r["template"] = template
    if poses or bodies:
        poses = list(poses or [])
        bodies = list(bodies or [])
        n = max(len(poses), len(bodies), len(r["bodies"]) if not poses and not bodies else 0)
        if poses and bodies and len(poses) != len(bodies) and 1 not in (len(poses), len(bodies)):
            msg = f"got {len(poses)} --pose and {len(bodies)} --body options; give one of them once or both equally often"
            raise RecipeError(msg)
        entries = []
        for i in range(n):
            base = copy.deepcopy(r["bodies"][min(i, len(r["bodies"]) - 1)])
            if bodies:
                spec = parse_body_spec(bodies[i] if len(bodies) > 1 else bodies[0])
                base["model"], base["params"] = spec["model"], {**spec["params"]}
            if poses:
                base["pose"] = poses[i] if len(poses) > 1 else poses[0]
                base.pop("name", None)
            entries.append(base)
        r["bodies"] = entries
    if sitters:
        if poses or bodies:
            raise RecipeError("--sitter designs one seat for several people: give it instead of --pose and --body, not with them")
        r["bodies"] = [parse_sitter_spec(spec) for spec in sitters]
        r["sitters"] = {"shared": True}
    for body in r["bodies"]:
        if mass is not None:
            body["params"]["mass"] = float(mass)
        if height is not None:
            body["params"]["height"] = float(height)
        if frame is not None:
            body["frame"] = int(frame)
    if refiners is not None:
        r["refiners"] = [{"name": n, "params": {}} for n in refiners if n]
    if exporters is not None:
        r["exporters"] = [n for n in exporters if n]
    if solver is not None:
        r["pressure"]["solver"] = solver
    if lam is not None:
        r["pressure"]["lambda"] = float(lam)
    if mu is not None:
        r["pressure"]["mu"] = float(mu)
    if output is not None:
        r["output"] = output
    if seed is not None:
        r["seed"] = int(seed)
    if surface_level is not None:
        r["surface_level"] = int(surface_level)
    if evaluate is not None:
        r["evaluate"]["enabled"] = bool(evaluate)
    if baseline is not None:
        r["evaluate"]["baseline"] = baseline or None
    if export_frame is not None:
        r["export_frame"] = export_frame
    for spec in options or ():
        step, key, value = parse_option_spec(spec)
        steps = r.setdefault("template_params", {}).setdefault("steps", {})
        if not isinstance(steps, dict):
            raise RecipeError(f"--option {spec}: the recipe's template_params.steps is not a mapping")
        steps.setdefault(step, {})[key] = value
    return r


def parse_option_spec(spec: str) -> tuple[str, str, Any]:
    """``STEP.KEY=VALUE`` of ``--option`` (a template step's option, as ``template_params.steps.STEP.KEY`` of a recipe): the step, the key and the value read as YAML.

    Raises
    ------
    RecipeError
        Not of that form.
    """
    name, sep, text = str(spec).partition("=")
    step, dot, key = name.strip().rpartition(".")
    if not sep or not dot or not step or not key or not text.strip():
        raise RecipeError(f"--option {spec}: expected STEP.KEY=VALUE, a template step's option (e.g. seat.height=0.5, border.width=0.08)")
    import yaml

    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        value = text.strip()
    return step.strip(), key.strip(), value


def check_recipe(recipe: Mapping, registry, *, document: Document | None = None) -> Recipe:
    """Check that every name and file in a normalised recipe exists, before any geometry.

    Returns
    -------
    Recipe
        The checked recipe (a copy of ``recipe``).

    Raises
    ------
    RecipeError
        Naming the key (and file and line when the recipe came from a file)
        and the names that exist.
    """
    _check_names(recipe, registry, document)
    return recipe if isinstance(recipe, Recipe) else Recipe.from_normalised(recipe)


def _check_names(recipe: Mapping, registry, document: Document | None) -> None:
    """:func:`check_recipe`'s checks."""

    def from_document(path, doc_path=None) -> bool:
        """Whether the value at ``path`` is the one the file gave at ``doc_path`` (default ``path``; not a flag's)."""
        if document is None:
            return False
        node_doc, node_rec = document.data, recipe
        try:
            for part in path:
                node_rec = node_rec[part]
            for part in path if doc_path is None else doc_path:
                node_doc = node_doc[part]
        except (KeyError, IndexError, TypeError):
            return False
        if doc_path is not None and len(doc_path) < len(path):  # a population's own key: a manikin's value comes from it
            return True
        if isinstance(node_rec, dict) and "name" in node_rec:  # a refiner: written as a name or {name, params}
            node_doc = node_doc.get("name") if isinstance(node_doc, dict) else node_doc
            node_rec = node_rec["name"]
        elif isinstance(node_doc, dict) and isinstance(node_rec, str):  # an exporter written as {name, params}
            node_doc = node_doc.get("name")
        return node_doc == node_rec or (isinstance(node_doc, str) and looks_like_path(node_doc))

    def fail(path, message):
        where = _sitters_path(recipe, document, tuple(path))
        if from_document(tuple(path), where):
            raise document.error(where, message)
        raise RecipeError(f"{format_path(where)}: {message}")

    def need(kind, name, path):
        try:
            registry.get(kind, name)
        except RecipeError as e:
            fail(path, str(e))

    def options_of(kind, name, path, given, params_path):
        """Check ``given`` against the declared options of component ``name`` (:mod:`seatkit.options`)."""
        component = _get(registry, kind, name)
        if component is None:
            return
        declared = getattr(component, "options", None) or {}

        def located(key_path, message):
            full = params_path + tuple(key_path)
            if document is not None and _in_document(document.data, full):
                return document.error(full, message)
            if document is not None and _in_document(document.data, params_path):
                return document.error(params_path, f"{format_path(key_path)}: {message}" if key_path else message)
            return RecipeError(f"{format_path(full)}: {message}")

        check_options(f"{kind.replace('_', ' ')} {name!r}", declared, given, fail=located)

    need("template", recipe["template"], ("template",))
    need("pressure_solver", recipe["pressure"]["solver"], ("pressure", "solver"))
    options_of("pressure_solver", recipe["pressure"]["solver"], ("pressure", "solver"), recipe["pressure"].get("options") or {}, ("pressure", "options"))
    for i, ref in enumerate(recipe["refiners"]):
        need("refiner", ref["name"], ("refiners", i))
        options_of("refiner", ref["name"], ("refiners", i), ref["params"], ("refiners", i, "params"))
    exporter_params = recipe.get("exporter_params") or {}
    for i, name in enumerate(recipe["exporters"]):
        need("exporter", name, ("exporters", i))
        options_of("exporter", name, ("exporters", i), exporter_params.get(name, {}), ("exporters", i, "params"))
    if recipe["evaluate"]["enabled"] and recipe["evaluate"]["baseline"]:
        need("template", recipe["evaluate"]["baseline"], ("evaluate", "baseline"))
        for i, ref in enumerate(recipe["evaluate"]["baseline_refiners"]):
            need("refiner", ref["name"], ("evaluate", "baseline_refiners", i))
            options_of("refiner", ref["name"], ("evaluate", "baseline_refiners", i), ref["params"], ("evaluate", "baseline_refiners", i, "params"))
    template = _get(registry, "template", recipe["template"])
    people = getattr(getattr(template, "spec", None), "people", None)
    if recipe.get("sitters") and people is not None and not people[0] <= 1 <= people[1]:
        fail(("template",), f"sitters share one seat, so the template is fitted to one person; {recipe['template']!r} fits {people[0]} to {people[1]} (people side by side go under bodies)")
    if template is not None:
        try:
            template.check_params(recipe["template_params"])
        except ParamError as e:
            fail(("template_params",) + e.path, e.problem)

    if recipe.get("structure", {}).get("enabled"):
        from seatkit.structure.build import check as check_structure

        for key, message in check_structure(recipe["structure"]):
            fail(("structure", key), message)

    def in_range(path, value, key, *, integer=False):
        """``value`` (from the file or a flag) is finite and within LIMITS[key]."""
        lo, hi, _, what = LIMITS[key]
        ok = not isinstance(value, bool) and isinstance(value, (int, float))
        if ok and integer:
            ok = isinstance(value, int)
        if ok:
            v = float(value) if abs(value) < 1e300 else math.inf
            ok = math.isfinite(v) and lo <= v <= hi
        if not ok:
            fail(path, f"expected {what}, got {quote(value)}")

    lam = recipe["pressure"]["lambda"]
    if lam != math.inf:
        in_range(("pressure", "lambda"), lam, "lambda")
    in_range(("pressure", "mu"), recipe["pressure"]["mu"], "mu")
    in_range(("evaluate", "support_distance"), recipe["evaluate"]["support_distance"], "support_distance")
    in_range(("seed",), recipe["seed"], "seed", integer=True)
    in_range(("surface_level",), recipe["surface_level"], "surface_level", integer=True)
    if "gap" in recipe["placement"]:
        in_range(("placement", "gap"), recipe["placement"]["gap"], "gap")
    frame = recipe.get("export_frame")
    if frame is not None and frame not in EXPORT_FRAMES:
        fail(("export_frame",), f"expected one of {', '.join(EXPORT_FRAMES)}, got {quote(frame)}")
    if frame == "capture" and len(recipe["bodies"]) != 1:
        fail(("export_frame",), f"capture needs one person (got {len(recipe['bodies'])}): a bench's people are each turned to face +Z, so they share no capture frame")
    for i, body in enumerate(recipe["bodies"]):
        need("body_model", body["model"], ("bodies", i, "model"))
        in_range(("bodies", i, "frame"), body.get("frame", 0), "frame", integer=True)
        for k, x in enumerate(body.get("offset") or ()):
            in_range(("bodies", i, "offset", k), x, "offset")
        mass = body["params"].get("mass", DEFAULT_BODY_MASS)
        finite = isinstance(mass, (int, float)) and not isinstance(mass, bool) and abs(mass) < 1e300
        if not finite or not (20.0 <= float(mass) <= 300.0):
            fail(("bodies", i, "params", "mass"), f"expected a body mass in kg between 20 and 300, got {quote(mass)}")
        path = body["params"].get("path")
        if path is not None and not (isinstance(path, str) and _is_file(path)):
            fail(("bodies", i, "params", "path"), f"file not found: {quote(path)}")
        _check_pose(body["pose"], ("bodies", i, "pose"), fail, registry)


def _sitters_path(recipe: Mapping, document: Document | None, path: tuple) -> tuple:
    """Where a body entry's value came from when the bodies are ``sitters``: ``sitters[i]...``, or the population's own key."""
    if not recipe.get("sitters") or not path or path[0] != "bodies" or document is None or "sitters" not in document.data:
        return path
    if isinstance(document.data["sitters"], Mapping):  # a population: its pose and frame are the mapping's
        return ("sitters", path[2]) if len(path) > 2 and path[2] in ("pose", "frame") else ("sitters",)
    return ("sitters", *path[1:])


def _in_document(data, path) -> bool:
    """Whether the key path ``path`` exists in the parsed file ``data``."""
    try:
        for part in path:
            data = data[part]
    except (KeyError, IndexError, TypeError):
        return False
    return True


def _get(registry, kind: str, name: str):
    try:
        return registry.get(kind, name)
    except RecipeError:
        return None


def _check_pose(spec: str, path, fail, registry) -> None:
    if looks_like_path(spec):
        if not _is_file(spec):
            fail(path, f"pose file not found: {quote(spec)}")
        return
    from seatkit.body.poses import pose_names

    names = pose_names(getattr(registry, "pose_dirs", None))  # the files are read when the pose is loaded
    if spec not in names:
        fail(path, f"unknown pose {quote(spec)}; library poses: {', '.join(names)} (or give a .yaml or .bvh path)")
