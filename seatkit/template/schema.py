"""The template YAML format: JSON schema, parameters with units, semantic checks.

A template file is read with :func:`seatkit.yamlio.load_yaml`, which keeps
the line of every key, validated against :data:`TEMPLATE_SCHEMA` and then
checked for meaning (segment names, grid shape, step names). Every problem
is reported as ``file:line: key.path: what was expected``, before any
geometry work. ``docs/templates.md`` describes every key.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from seatkit.errors import ParamError, RecipeError
from seatkit.template.options import did_you_mean
from seatkit.skeleton import SEGMENT_INDEX, SEGMENTS
from seatkit.messages import quote
from seatkit.yamlio import Document, parse_yaml, read_text, validate

__all__ = [
    "PARAMETERS",
    "TEMPLATE_SCHEMA",
    "FaceSpec",
    "TemplateSpec",
    "read_template",
    "resolve_parameters",
]

#: Every template parameter: default, unit, meaning. A template's
#: ``parameters:`` overrides the default, a recipe's ``template_params``
#: overrides the template. Angles are degrees here (``*_deg``) and radians
#: inside the code.
PARAMETERS: dict[str, tuple[float, str, str]] = {
    "ransac_iterations": (300, "count", "candidate planes drawn per face"),
    "support_distance": (0.02, "m", "a body vertex this close to a plane is supported"),
    "max_penetration": (0.006, "m", "how far a plane may sink into the skin"),
    "lambda_r": (0.5, "1", "weight of the PCA-normal penalty p^r"),
    "lambda_d": (0.5, "1", "weight of the row-direction penalty p^d"),
    "m_alpha_deg": (30.0, "deg", "deviation of d^ir from d^side where p^d reaches 0"),
    "max_row_angle_deg": (60.0, "deg", "row line deviation that would degenerate a face (rejected)"),
    "max_side_angle_deg": (30.0, "deg", "a fitted face's d_side may deviate this much from the body's right-to-left axis"),
    "max_wrap_deg": (60.0, "deg", "an outer face's d_side may deviate this much from the right-to-left axis (it wraps around the body)"),
    "min_dihedral_deg": (10.0, "deg", "planes closer than this meet at the joint, not at their intersection"),
    "max_line_offset": (0.12, "m", "a row line farther than this from its joint is replaced by the joint line"),
    "importance_floor": (1e-3, "1", "added to the importance so that unloaded segments still get a plane"),
    "max_neighbour_cut": (0.02, "1", "fraction of adjacent-segment vertices a plane may cut under its patch"),
    "important_threshold": (0.05, "1", "importance (fraction of the peak) above which a vertex is important"),
    "end_margin": (0.03, "m", "how far the first and last rows reach beyond their segment"),
    "fit_attempts": (6, "count", "RANSAC starts tried (the seed's, then fixed fallbacks) before the optional steps are dropped"),
}

#: Largest value of a parameter, by unit: a bound that keeps a build finite
#: in time and memory (``ransac_iterations: 1e12`` would not be) and the
#: geometry meaningful (a support distance of a kilometre is not).
PARAMETER_MAXIMA: dict[str, float] = {"count": 20_000, "m": 1.0, "deg": 180.0, "1": 100.0}

#: Tighter maxima of single parameters. ``fit_attempts`` multiplies the
#: template stage's worst case (a refused pose runs every start, (1 +
#: optional steps) x fit_attempts of them, about 0.3-0.6 s each on the
#: chair): 20 bounds a refusal of the chair at 80 starts, well under a
#: minute, where 20,000 would be hours (docs/templates.md, "The starts").
PARAMETER_LIMITS: dict[str, float] = {"fit_attempts": 20}


def parameter_maximum(key: str) -> float:
    """The largest value parameter ``key`` may take."""
    return PARAMETER_LIMITS.get(key, PARAMETER_MAXIMA[PARAMETERS[key][1]])

#: Most people a template may seat.
MAX_PEOPLE = 64


def _parameter_schema(key: str, unit: str) -> dict:
    kind = "integer" if unit == "count" else "number"
    return {"type": kind, "minimum": 1 if unit == "count" else 0, "maximum": parameter_maximum(key)}


def parameter_problem(key: str, value: Any) -> str | None:
    """What is wrong with ``value`` for parameter ``key`` (None if nothing).

    Counts are whole numbers (``2.5`` and ``1.0e+12`` are refused, not
    truncated), the rest finite numbers from 0 to :data:`PARAMETER_MAXIMA`
    (or the parameter's own :data:`PARAMETER_LIMITS`).
    """
    unit = PARAMETERS[key][1]
    hi = parameter_maximum(key)
    if unit == "count":
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= hi:
            return f"expected a whole number from 1 to {int(hi)} ({unit}), got {quote(value)}"
        return None
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and abs(value) < 1e300
    if not ok or not math.isfinite(value) or not 0 <= value <= hi:
        return f"expected a number from 0 to {hi:g} ({unit}), got {quote(value)}"
    return None


_NAME = {"type": "string", "pattern": "^[A-Za-z][A-Za-z0-9_.-]*$", "maxLength": 100}
_SEGMENT = {"type": "string", "enum": list(SEGMENTS)}

_FACE = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "role": {"enum": ["fit", "bridge", "outer"], "description": "fit: own RANSAC plane; bridge: joins its neighbours; outer: plane through the inner column's vertices"},
        "segments": {"type": "array", "items": _SEGMENT, "minItems": 1, "uniqueItems": True},
        "label": {"type": "string"},
        "width_fraction": {"type": "number", "exclusiveMinimum": 0, "maximum": 1},
    },
}

TEMPLATE_SCHEMA: dict = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "additionalProperties": False,
    "required": ["name", "columns", "rows", "steps"],
    "properties": {
        "name": _NAME,
        "description": {"type": "string"},
        "people": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "min": {"type": "integer", "minimum": 1, "maximum": MAX_PEOPLE},
                "max": {"type": "integer", "minimum": 1, "maximum": MAX_PEOPLE},
            },
        },
        "parameters": {
            "type": "object",
            "additionalProperties": False,
            "properties": {k: _parameter_schema(k, u) for k, (_, u, _) in PARAMETERS.items()},
        },
        "columns": {"type": "array", "items": _NAME, "minItems": 1, "uniqueItems": True},
        "rows": {
            "type": "array",
            "minItems": 1,
            "items": {
                "type": "object",
                "additionalProperties": False,
                "required": ["name", "faces"],
                "properties": {
                    "name": _NAME,
                    "faces": {"type": "object", "additionalProperties": _FACE},
                },
            },
        },
        "steps": {
            "type": "array",
            "minItems": 1,
            "items": {
                "type": "object",
                "required": ["step"],
                "properties": {"step": _NAME, "label": _NAME},
            },
        },
    },
}


@dataclass(frozen=True)
class FaceSpec:
    """One face of the grid as declared.

    Attributes
    ----------
    row, column : int
        Grid position (rows from the first listed, columns along d_side).
    role : str
        ``fit``, ``bridge`` or ``outer``.
    segments : tuple of int
        Body segments it supports (indices into :data:`seatkit.skeleton.SEGMENTS`).
    label : str
        Role shown in reports (``thigh.right``).
    width_fraction : float
        Fraction of the segment's width the face spans (fit faces).
    """

    row: int
    column: int
    role: str
    segments: tuple
    label: str
    width_fraction: float = 1.0


@dataclass
class TemplateSpec:
    """A validated template document.

    Attributes
    ----------
    name, description : str
    source : str
        File it came from.
    columns, rows : list of str
        Column names (along d_side) and row names (from the first row up).
    faces : dict of (int, int) to FaceSpec
    steps : list of dict
        Each ``{"step": name, **options}`` as written.
    parameters : dict of str to float
        Declared parameter values (degrees as written).
    people : (int, int)
        Fewest and most bodies the template fits.
    doc : Document
        The parsed document, for located error messages at fit time.
    """

    name: str
    description: str
    source: str
    columns: list
    rows: list
    faces: dict
    steps: list
    parameters: dict
    people: tuple
    doc: Document = field(repr=False, default=None)

    def where(self, path) -> str:
        """``file:line: key.path`` of a key of this template."""
        return self.doc.where(path)


#: SHA-256 digests (:func:`template_digest`) of the shipped templates'
#: text (``templates/*.yaml``), each checked against :data:`TEMPLATE_SCHEMA`
#: by the test suite (``tests/test_template_engine.py``, which fails and
#: prints the new digest when a shipped template changes). A template of
#: exactly this text skips the schema check when it is read (jsonschema's
#: import and validator: about 0.05 s of every build); every other one, an
#: edited shipped template included, is checked. The checks of meaning
#: that follow the schema run for every template.
CHECKED_TEMPLATES = frozenset(
    {
        "ce1b357553e5de759992326f1515d13e9bbf38e2dbc10fa5be847c9a65c79184",  # bench.yaml
        "45aaa5f05a9f1124ac5c08f19a7a60bd872e722c1611c196d271434be67e2880",  # chair.yaml
        "901d76cce82bb7e6e74322af48c8e723f5e67113b69016d9c0cc9a054a6f45c0",  # saddle.yaml
    }
)


def template_digest(text: str) -> str:
    """The SHA-256 digest of a template's text, line ends as ``\\n`` (:data:`CHECKED_TEMPLATES`)."""
    return hashlib.sha256(text.replace("\r\n", "\n").encode("utf-8")).hexdigest()


def read_template(source: str | Path, *, text: str | None = None) -> TemplateSpec:
    """Read, validate and check a template.

    Parameters
    ----------
    source : str or Path
        File to read (or, with ``text``, the name used in messages).
    text : str, optional
        YAML text to parse instead of reading ``source``.

    Returns
    -------
    TemplateSpec

    Raises
    ------
    RecipeError
        ``file:line: key.path: problem`` for every schema or meaning error.
    """
    if text is None:
        source = Path(source)
        text = read_text(source, "YAML file")
    doc = parse_yaml(text, source=str(source))
    if not isinstance(doc.data, dict):
        raise doc.error((), f"a template must be a mapping (name, columns, rows, steps), got {type(doc.data).__name__}")
    if template_digest(text) not in CHECKED_TEMPLATES:
        validate(doc, TEMPLATE_SCHEMA)
    data = doc.data
    columns = list(data["columns"])
    rows = [r["name"] for r in data["rows"]]
    if len(set(rows)) != len(rows):
        dup = next(n for n in rows if rows.count(n) > 1)
        raise doc.error(("rows", rows.index(dup, rows.index(dup) + 1), "name"), f"row {quote(dup)} is declared twice")
    faces: dict = {}
    for r, row in enumerate(data["rows"]):
        declared = row["faces"]
        for name in declared:
            if name not in columns:
                raise doc.error(("rows", r, "faces", name), f"unknown column {quote(name)}; the columns are {', '.join(columns)}")
        for c, col in enumerate(columns):
            if col not in declared:
                raise doc.error(("rows", r, "faces"), f"row {quote(row['name'])} has no face for column {quote(col)}; every row needs one face per column ({', '.join(columns)})")
            f = declared[col]
            role = f.get("role", "fit")
            segs = f.get("segments", [])
            if role in ("fit", "outer") and not segs:
                raise doc.error(("rows", r, "faces", col), f"a {role!r} face needs 'segments' (body segments it supports, e.g. [RightUpLeg])")
            if role == "bridge" and segs:
                raise doc.error(("rows", r, "faces", col, "segments"), "a 'bridge' face supports no segment of its own; remove 'segments' or use role 'fit'")
            label = f.get("label", f"{row['name']}.{col}")
            faces[(r, c)] = FaceSpec(r, c, role, tuple(SEGMENT_INDEX[s] for s in segs), label, float(f.get("width_fraction", 1.0)))
    _check_roles(doc, columns, faces)
    people = data.get("people", {})
    lo, hi = int(people.get("min", 1)), int(people.get("max", 1))
    if hi < lo:
        raise doc.error(("people", "max"), f"people.max ({hi}) is smaller than people.min ({lo})")
    steps = []
    for i, s in enumerate(data["steps"]):
        steps.append(dict(s))
        for key in ("rows", "columns"):
            if key in s:
                names = rows if key == "rows" else columns
                vals = s[key]
                if not isinstance(vals, list) or not all(isinstance(v, str) for v in vals):
                    raise doc.error(("steps", i, key), f"expected a list of {key[:-1]} names, got {quote(vals)}")
                for j, v in enumerate(vals):
                    if v not in names:
                        raise doc.error(("steps", i, key, j), f"unknown {key[:-1]} {quote(v)}; expected one of {', '.join(names)}")
    params = dict(data.get("parameters", {}))
    return TemplateSpec(
        name=data["name"],
        description=data.get("description", ""),
        source=str(source),
        columns=columns,
        rows=rows,
        faces=faces,
        steps=steps,
        parameters=params,
        people=(lo, hi),
        doc=doc,
    )


def _check_roles(doc: Document, columns: list, faces: dict) -> None:
    """A face's role must suit its column: 'outer' at an end next to a 'fit' face, 'bridge' between two 'fit' faces."""
    C = len(columns)
    for (r, c), f in sorted(faces.items()):
        if f.role == "outer" and (c not in (0, C - 1) or C < 2):
            ends = f"{columns[0]!r} or {columns[-1]!r}" if C > 1 else "(none: one column)"
            msg = f"role 'outer' fits a face of an end column ({ends}) through its inner neighbour's vertices; column {columns[c]!r} is not an end column"
            raise doc.error(("rows", r, "faces", columns[c], "role"), msg)
    for (r, c), f in sorted(faces.items()):
        path = ("rows", r, "faces", columns[c], "role")
        if f.role == "outer":
            inner = c + 1 if c == 0 else c - 1
            if faces[(r, inner)].role != "fit":
                raise doc.error(path, f"role 'outer' needs a 'fit' face beside it in column {columns[inner]!r}, which is {faces[(r, inner)].role!r}")
        elif f.role == "bridge":
            if not 0 < c < C - 1 or faces[(r, c - 1)].role != "fit" or faces[(r, c + 1)].role != "fit":
                raise doc.error(path, f"role 'bridge' joins the 'fit' faces on both sides of it; column {columns[c]!r} has no 'fit' face on both sides")


def resolve_parameters(spec: TemplateSpec, overrides: Mapping[str, Any] | None) -> dict:
    """Defaults, then the template's values, then ``overrides``; angles to radians.

    Returns
    -------
    dict
        Every parameter of :data:`PARAMETERS`; ``*_deg`` keys are also given
        in radians under the name without the suffix (``m_alpha``).

    Raises
    ------
    ParamError
        For an unknown parameter or a value of the wrong type (key path
        inside ``template_params``).
    """
    values = {k: v for k, (v, _, _) in PARAMETERS.items()}
    values.update(spec.parameters)
    for key, value in (overrides or {}).items():
        if key not in PARAMETERS:
            labels = [str(s.get("label", s["step"])) for s in spec.steps]
            if key in labels:
                hint = f"; step options go under steps: (template_params: {{steps: {{{key}: {{...}}}}}})"
            else:
                hint = did_you_mean(key, list(PARAMETERS) + ["steps"])
            msg = f"unknown parameter of template {spec.name!r}; expected one of {', '.join(PARAMETERS)} or steps{hint}"
            raise ParamError((key,), msg)
        problem = parameter_problem(key, value)
        if problem:
            raise ParamError((key,), problem)
        values[key] = value
    values["ransac_iterations"] = int(values["ransac_iterations"])
    values["fit_attempts"] = int(values["fit_attempts"])
    for key in list(values):
        if key.endswith("_deg"):
            values[key[: -len("_deg")]] = math.radians(values[key])
    return values
