"""The import graph of seatkit/ and plugins/: no cycles, nothing imports up the layers, and the docs say so.

Every import statement counts, at module level or inside a function or an
``if TYPE_CHECKING:`` block (an import hidden in a function still makes the
two modules depend on each other). The layers are the table of
docs/architecture.md ("Layers"): a module may import modules of its own
layer or of a lower one, never of a higher one, and never in a cycle. The
table must name every module (a row ``seatkit.body.*`` covers the package
and every module inside it that has no row of its own) and only modules that
exist, and the diagram
above it must list the same names layer by layer, so the document cannot
drift from the code (datasette's documentation tests are the model).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ARCHITECTURE = ROOT / "docs" / "architecture.md"

#: Imports known to go up the layers, each owned by another part of issue 16
#: and to be removed with it (the test fails when one of them is gone, so the
#: entry is deleted with it). Nothing may be added here without an owner.
PENDING: dict[tuple[str, str], str] = {}


def _modules() -> dict[str, Path]:
    """Every module of seatkit/ and plugins/ by its import name."""
    out = {}
    for base, prefix in ((ROOT / "seatkit", ("seatkit",)), (ROOT / "plugins", ())):
        for path in sorted(base.rglob("*.py")):
            parts = prefix + path.relative_to(base).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The module of ours an imported name lives in (``seatkit.body.bvh.load_bvh`` -> ``seatkit.body.bvh``)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def imports_of(module: str) -> dict[str, int]:
    """Modules of ours that ``module`` imports, each with the line of its first import."""
    path = MODULES[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: dict[str, int] = {}
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1])
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            # ``from seatkit.body import rig`` imports the module seatkit.body.rig,
            # ``from seatkit.body import load_rig`` the package seatkit.body
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names]
        for target in targets:
            resolved = _resolve(target)
            if resolved is not None and resolved != module:
                found.setdefault(resolved, node.lineno)
    return found


GRAPH = {m: imports_of(m) for m in MODULES}


def _layer_table() -> tuple[dict[str, int], dict[int, str]]:
    """docs/architecture.md's table: module pattern -> layer number, and layer number -> layer name."""
    text = ARCHITECTURE.read_text()
    section = text.split("<!-- layer table -->", 1)[1].split("<!-- end layer table -->", 1)[0]
    rows, names = {}, {}
    for line in section.splitlines():
        m = re.match(r"\|\s*(\d+)\s+(\w[\w-]*)\s*\|\s*`([\w.*]+)`\s*\|", line)
        if m:
            layer, name, module = int(m.group(1)), m.group(2), m.group(3)
            assert module not in rows, f"docs/architecture.md: {module} is in the layer table twice"
            rows[module] = layer
            assert names.setdefault(layer, name) == name, f"docs/architecture.md: layer {layer} has two names"
    return rows, names


ROWS, LAYER_NAMES = _layer_table()


def _row_of(module: str) -> str | None:
    """The table row that covers ``module``: its own (``seatkit.cli``), else its nearest package's (``seatkit.body.*``)."""
    if module in ROWS:
        return module
    name = module
    while name:
        if f"{name}.*" in ROWS:
            return f"{name}.*"
        name = name.rpartition(".")[0]
    return None


def layer_of(module: str) -> int:
    return ROWS[_row_of(module)]


def test_the_layer_table_names_every_module_and_only_modules_that_exist():
    assert len(ROWS) > 10, "docs/architecture.md: the layer table was not found (<!-- layer table --> ... <!-- end layer table -->)"
    missing = sorted(m for m in MODULES if _row_of(m) is None)
    assert not missing, f"docs/architecture.md's layer table does not place these modules: {missing}"
    stale = sorted(r for r in ROWS if r.removesuffix(".*") not in MODULES)
    assert not stale, f"docs/architecture.md's layer table names modules that do not exist: {stale}"


def _diagram() -> list[tuple[int, str, set[str]]]:
    """docs/architecture.md's diagram: (layer, name, module patterns) from the top down.

    A layer's line is ``layer N  name  a, b.*, ...``; its names may go on over
    the next indented lines; a name without a ``seatkit_`` prefix is under
    ``seatkit.`` (``body.*`` is ``seatkit.body.*``, ``seatkit`` the package).
    """
    text = ARCHITECTURE.read_text()
    diagram = text.split("<!-- layer diagram -->", 1)[1].split("<!-- end layer diagram -->", 1)[0]
    out: list[tuple[int, str, set[str]]] = []
    for line in diagram.splitlines():
        head = re.match(r"\s*layer (\d+)\s+(\w[\w-]*)\s+(.*)$", line)
        more = re.match(r"\s+([\w.*]+,.*|[\w.*]+)$", line)
        if head:
            out.append((int(head.group(1)), head.group(2), set()))
            names = head.group(3)
        elif more and out:
            names = more.group(1)
        else:
            continue
        for name in re.findall(r"[\w.*]+", names):
            out[-1][2].add(name if name == "seatkit" or name.startswith("seatkit_") else f"seatkit.{name}")
    return out


def test_the_diagram_shows_the_layers_of_the_table():
    diagram = _diagram()
    assert diagram, "docs/architecture.md: the layer diagram was not found (<!-- layer diagram --> ... <!-- end layer diagram -->)"
    order = [layer for layer, _, _ in diagram]
    assert order == sorted(LAYER_NAMES, reverse=True), f"docs/architecture.md: the diagram shows layers {order}, the table {sorted(LAYER_NAMES, reverse=True)} (from the top down)"
    for layer, name, shown in diagram:
        assert LAYER_NAMES[layer] == name, f"docs/architecture.md: the diagram calls layer {layer} {name!r}, the table {LAYER_NAMES[layer]!r}"
        in_table = {row for row, at in ROWS.items() if at == layer}
        assert shown == in_table, f"docs/architecture.md: layer {layer} of the diagram shows {sorted(shown - in_table)} that the table does not, and misses {sorted(in_table - shown)}"


def _upward() -> dict[tuple[str, str], int]:
    return {
        (m, target): line
        for m, targets in GRAPH.items()
        for target, line in targets.items()
        if layer_of(target) > layer_of(m)
    }


def test_no_module_imports_a_higher_layer():
    up = _upward()
    new = {edge: line for edge, line in up.items() if edge not in PENDING}
    shown = [f"{MODULES[m].relative_to(ROOT)}:{line}: {m} (layer {layer_of(m)}) imports {t} (layer {layer_of(t)})" for (m, t), line in sorted(new.items())]
    assert not shown, "imports up the layers of docs/architecture.md:\n" + "\n".join(shown)
    gone = sorted(edge for edge in PENDING if edge not in up)
    assert not gone, f"these pending imports are gone: delete their PENDING entries in {Path(__file__).name}: {gone}"


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                part = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    part.append(top)
                    if top == node:
                        break
                if len(part) > 1:
                    out.append(sorted(part))
    return out


def test_no_import_cycles():
    graph = {m: {t for t in targets if (m, t) not in PENDING} for m, targets in GRAPH.items()}
    cycles = _cycles(graph)
    shown = []
    for part in cycles:
        inside = set(part)
        shown.append(", ".join(f"{m} -> {t} ({MODULES[m].relative_to(ROOT)}:{GRAPH[m][t]})" for m in part for t in sorted(graph[m] & inside)))
    assert not cycles, "import cycles:\n" + "\n".join(shown)


@pytest.mark.parametrize(
    ("graph", "expected"),
    [
        ({"a": {"b"}, "b": {"c"}, "c": set()}, []),
        ({"a": {"b"}, "b": {"a"}}, [["a", "b"]]),
        ({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}, [["a", "b", "c"]]),
        ({"a": {"a"}}, []),
    ],
)
def test_the_cycle_finder_itself(graph, expected):
    assert _cycles(graph) == expected


def test_the_scanner_sees_imports_inside_functions():
    # the hidden cycles issue 16 found were imports inside functions: the scanner must see them
    assert "seatkit.subdivision.limit" in GRAPH["seatkit.subdivision.catmull_clark"]
    assert "seatkit.body.rig" in GRAPH["seatkit.body.gltf"]
    assert "seatkit.pipeline" in GRAPH["seatkit.cli"], "seatkit/cli.py imports the pipeline inside a function; the scanner missed it"
