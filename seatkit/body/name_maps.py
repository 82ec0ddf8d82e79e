"""Name maps: which joints of a BVH file or a glTF skin drive each of the 21 segments.

A name map (YAML, ``seatkit/data/name_maps/``) lists for each segment the
joint names that drive it, and the extra joints of its convention (fingers,
toes, end joints). The built-in Perception Neuron, CMU and Mixamo maps are
tried and the one that recognises most joint names of the file wins
(:func:`candidate_maps`, :func:`choose_map`). Names match case-insensitively
after dropping a namespace prefix (``mixamorig:``). A user map (a YAML path
or a dict) is laid over every built-in one: its names come first for the
segments it lists (``base: cmu`` picks the built-in map it extends;
``base: none`` uses it alone). The BVH reader (:mod:`seatkit.body.bvh`), the
glTF reader (:mod:`seatkit.body.gltf`) and the anny plugin use them.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import yaml

from seatkit.errors import InputError, RecipeError
from seatkit.messages import clip, quote
from seatkit.resources import data_path
from seatkit.skeleton import N_SEGMENTS, SEGMENT_INDEX, SEGMENTS

__all__ = [
    "BUILTIN_BVH_MAPS",
    "REQUIRED_SEGMENTS",
    "NameMap",
    "load_name_map",
    "candidate_maps",
    "choose_map",
]

#: Built-in BVH name maps, in the order they are tried.
BUILTIN_BVH_MAPS: tuple[str, ...] = ("perception-neuron", "cmu", "mixamo")

#: Segments a BVH (or glTF skin) must provide; the others (Spine..Spine3,
#: Neck, Shoulders) may be missing and then follow their parent.
REQUIRED_SEGMENTS: tuple[str, ...] = (
    "Hips",
    "RightUpLeg",
    "RightLeg",
    "RightFoot",
    "LeftUpLeg",
    "LeftLeg",
    "LeftFoot",
    "Head",
    "RightArm",
    "RightForeArm",
    "RightHand",
    "LeftArm",
    "LeftForeArm",
    "LeftHand",
)


def _normalise_name(name: str) -> str:
    """Joint name for matching: namespace dropped (``mixamorig:Hips``), lower case."""
    return name.rsplit(":", 1)[-1].strip().lower()


@dataclass(frozen=True)
class NameMap:
    """Joint names of one convention, per seatkit segment.

    Attributes
    ----------
    name : str
    segments : dict of str to tuple of str
        Segment name -> accepted joint names, in order of preference.
    known : tuple of str
        Extra joint names of this convention that are not mapped.
    bvh_channel_order : str
        Euler order (e.g. ``"ZXY"``) :func:`write_bvh` uses (``""``: ZXY).
    namespaces : tuple of str
        Name prefixes (``mixamorig`` of ``mixamorig:Hips``) typical of this
        convention: each joint carrying one counts once more when choosing a
        map, and :func:`write_bvh` writes the first.
    source : str
        File it came from.
    """

    name: str
    segments: dict
    known: tuple = ()
    bvh_channel_order: str = ""
    namespaces: tuple = ()
    source: str = ""
    description: str = ""

    def resolve(self, names: Sequence[str]) -> tuple[np.ndarray, int]:
        """Find each segment's joint among ``names``.

        Parameters
        ----------
        names : sequence of str
            Joint names of a file.

        Returns
        -------
        index : (21,) int64
            Index into ``names`` of each segment's joint, -1 where none.
        score : int
            How many of ``names`` this map recognises (mapped or known).
        """
        lookup: dict[str, int] = {}
        for i, n in enumerate(names):
            lookup.setdefault(_normalise_name(n), i)
        index = np.full(N_SEGMENTS, -1, dtype=np.int64)
        used: set[int] = set()
        for seg, aliases in self.segments.items():
            for alias in aliases:
                j = lookup.get(_normalise_name(alias))
                if j is not None and j not in used:
                    index[SEGMENT_INDEX[seg]] = j
                    used.add(j)
                    break
        recognised = {_normalise_name(a) for aliases in self.segments.values() for a in aliases}
        recognised |= {_normalise_name(a) for a in self.known}
        score = sum(1 for key in lookup if key in recognised)
        spaces = {ns.lower() for ns in self.namespaces}
        score += sum(1 for n in names if ":" in n and n.rsplit(":", 1)[0].strip().lower() in spaces)
        return index, score

    def missing(self, index: np.ndarray, required: Sequence[str] = REQUIRED_SEGMENTS) -> list[str]:
        """Required segments that ``index`` (from :meth:`resolve`) leaves without a joint."""
        return [s for s in required if index[SEGMENT_INDEX[s]] < 0]

    def overlaid(self, user: "NameMap") -> "NameMap":
        """This map with ``user``'s names first for the segments it lists."""
        segments = {k: tuple(v) for k, v in self.segments.items()}
        for seg, aliases in user.segments.items():
            segments[seg] = tuple(aliases) + tuple(a for a in segments.get(seg, ()) if a not in aliases)
        return NameMap(
            name=f"{user.name}+{self.name}",
            segments=segments,
            known=tuple(self.known) + tuple(user.known),
            bvh_channel_order=user.bvh_channel_order or self.bvh_channel_order,
            namespaces=tuple(user.namespaces) + tuple(self.namespaces),
            source=user.source,
            description=user.description or self.description,
        )


def _name_map_from_dict(data: Any, source: str) -> NameMap:
    if not isinstance(data, Mapping):
        msg = f"{source}: a name map must be a mapping with a 'segments' key, got {type(data).__name__}"
        raise InputError(msg)
    allowed = {"name", "description", "segments", "known", "bvh_channel_order", "namespaces", "base"}
    unknown_keys = set(data) - allowed
    if unknown_keys:
        msg = (
            f"{source}: unknown key(s) {', '.join(sorted(map(str, unknown_keys)))}; expected "
            f"{', '.join(sorted(allowed))}"
        )
        raise InputError(msg)
    raw = data.get("segments")
    if not isinstance(raw, Mapping):
        msg = f"{source}: 'segments' must map segment names to lists of joint names"
        raise InputError(msg)
    segments: dict[str, tuple[str, ...]] = {}
    for seg, aliases in raw.items():
        if seg not in SEGMENT_INDEX:
            msg = f"{source}: segments.{clip(seg)}: unknown segment; expected one of {', '.join(SEGMENTS)}"
            raise InputError(msg)
        if isinstance(aliases, str):
            aliases = [aliases]
        if not isinstance(aliases, list) or not all(isinstance(a, str) for a in aliases):
            msg = f"{source}: segments.{seg}: expected a list of joint names, got {quote(aliases)}"
            raise InputError(msg)
        segments[seg] = tuple(aliases)
    known = data.get("known") or []
    if not isinstance(known, list) or not all(isinstance(a, str) for a in known):
        msg = f"{source}: 'known' must be a list of joint names"
        raise InputError(msg)
    namespaces = data.get("namespaces") or []
    if not isinstance(namespaces, list) or not all(isinstance(a, str) for a in namespaces):
        msg = f"{source}: 'namespaces' must be a list of name prefixes"
        raise InputError(msg)
    order = str(data.get("bvh_channel_order", "")).upper()
    if order and sorted(order) != ["X", "Y", "Z"]:
        msg = f"{source}: bvh_channel_order: expected a permutation of XYZ, got {quote(order)}"
        raise InputError(msg)
    return NameMap(
        name=str(data.get("name", Path(source).stem)),
        segments=segments,
        known=tuple(known),
        bvh_channel_order=order,
        namespaces=tuple(namespaces),
        source=source,
        description=str(data.get("description", "")),
    )


@functools.lru_cache(maxsize=None)
def _builtin_name_map(name: str) -> NameMap:
    """A packaged name map, parsed once per process (every BVH and glTF load asks for them)."""
    builtin = data_path("name_maps", f"{name}.yaml")
    return _name_map_from_dict(yaml.load(builtin.read_text(encoding="utf-8"), Loader=_FAST_LOADER), f"{name}.yaml")


_FAST_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _read_yaml(path: Path):
    """A user's name map through seatkit's safe YAML loader (see seatkit.yamlio)."""
    from seatkit.yamlio import load_yaml

    try:
        return load_yaml(path, "name map").data
    except RecipeError as e:
        raise InputError(str(e)) from None


def load_name_map(name_map: str | Path | Mapping) -> NameMap:
    """Load a name map: a built-in name, a YAML path, or a dict.

    Parameters
    ----------
    name_map : str, Path or mapping
        ``"perception-neuron"``, ``"cmu"``, ``"mixamo"``, ``"gltf-default"``,
        a path to a YAML file, or the parsed mapping (see
        ``seatkit/data/name_maps/perception-neuron.yaml`` for the format).

    Returns
    -------
    NameMap
    """
    if isinstance(name_map, Mapping):
        return _name_map_from_dict(name_map, "<name map>")
    text_name = str(name_map)
    builtin = data_path("name_maps", f"{text_name}.yaml")
    if "/" not in text_name and not text_name.endswith((".yaml", ".yml")) and builtin.is_file():
        return _builtin_name_map(text_name)
    path = Path(name_map)
    if not path.is_file():
        names = sorted(p.stem for p in data_path("name_maps").glob("*.yaml"))
        msg = f"name map {text_name!r}: no such file, and not a built-in map ({', '.join(names)})"
        raise InputError(msg)
    return _name_map_from_dict(_read_yaml(path), str(path))


def candidate_maps(name_map, builtins: Sequence[str]) -> list[NameMap]:
    """The maps to try: built-ins, each overlaid with the user's map if given."""
    if name_map is None:
        return [load_name_map(b) for b in builtins]
    if isinstance(name_map, str) and name_map in builtins:
        return [load_name_map(name_map)]
    user_raw = name_map
    base = None
    if isinstance(name_map, Mapping):
        base = name_map.get("base")
    else:
        path = Path(name_map)
        if path.is_file():
            data = _read_yaml(path)
            if isinstance(data, Mapping):
                base = data.get("base")
    user = load_name_map(user_raw)
    if base is not None and str(base).lower() == "none":
        return [user]
    bases = [str(base)] if base is not None else list(builtins)
    return [load_name_map(b).overlaid(user) for b in bases]


def choose_map(names: Sequence[str], maps: Sequence[NameMap]) -> tuple[NameMap, np.ndarray]:
    """The map recognising most of ``names`` (ties: fewest missing segments, then order)."""
    best = None
    for rank, m in enumerate(maps):
        index, score = m.resolve(names)
        key = (score, -len(m.missing(index)), -rank)
        if best is None or key > best[0]:
            best = (key, m, index)
    return best[1], best[2]
