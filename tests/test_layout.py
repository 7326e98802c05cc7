"""The code's layout: imports follow the data flow, no import circles, no oversized pieces.

Layers, lowest first (a module may import its own package and anything lower, never a
package above it; packages on one layer do not import each other):

0. ``errors``, ``sensor_types``
1. ``config``
2. ``geometry``, ``messages``, ``zones`` (who is in which zone, who crossed a door)

3. ``transport``, ``recordings`` (the files a site's messages are recorded in)
4. ``security`` (a secured session's settings, from the network file and the keys)
5. ``runtime``
6. ``detection``, ``tracking``
7. ``output``, ``calibration`` (the calibration file, its service on the bus, the
   solvers), ``analytics``, ``replayer``
8. ``sim``, ``recorder`` (it checks calibration entries too)
9. ``eval``
10. ``launch``, ``nodes`` (the node entry points, shipped as ``openptrack_py.nodes``)
11. ``cli``

Every import counts, including the ones inside functions (a lazy import is still a
dependency); only imports under ``if TYPE_CHECKING:`` are ignored.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "openptrack_py"

LAYERS: dict[str, int] = {
    "errors": 0,
    "sensor_types": 0,
    "config": 1,
    "geometry": 2,
    "messages": 2,
    "zones": 2,
    "transport": 3,
    "security": 4,
    "runtime": 5,
    "detection": 6,
    "tracking": 6,
    "output": 7,
    "recorder": 8,
    "recordings": 3,
    "analytics": 7,
    "replayer": 7,
    "calibration": 7,
    "sim": 8,
    "eval": 9,
    "launch": 10,
    "nodes": 10,
    "presets": 10,
    "cli": 11,
}
MAX_FILE_LINES = 500
MAX_FUNCTION_LINES = 80
LONG_FILE_REASON = "long because"
"""A file over the limit says why in its docstring, with these words."""


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in ast.walk(node):
                if hasattr(child, "lineno"):
                    lines.add(child.lineno)
    return lines


def _imports(name: str, path: Path) -> Iterator[tuple[str, int]]:
    """Modules of ``openptrack_py`` that ``name`` imports, with the line."""
    tree = ast.parse(path.read_text(), str(path))
    skip = _type_checking_lines(tree)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(tree):
        if getattr(node, "lineno", None) in skip:
            continue
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            # `from pkg import mod` depends on pkg.mod when that is a module
            targets = [
                f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base
                for alias in node.names
            ]
        else:
            continue
        for target in targets:
            if target.split(".")[0] == "openptrack_py":
                yield target, node.lineno


def _top(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


GRAPH = {name: sorted({t for t, _ in _imports(name, path)}) for name, path in MODULES.items()}


def test_every_package_has_a_layer() -> None:
    tops = {_top(name) for name in MODULES} - {""}
    assert tops <= set(LAYERS), f"give these a layer in LAYERS: {sorted(tops - set(LAYERS))}"


def test_no_import_goes_up_the_data_flow() -> None:
    bad = []
    for name, path in MODULES.items():
        src = _top(name)
        if not src:
            continue
        for target, line in _imports(name, path):
            dst = _top(target)
            if not dst or dst == src:
                continue
            if LAYERS[dst] >= LAYERS[src]:
                bad.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {name} -> {target}")
    assert not bad, "imports against the data flow:\n" + "\n".join(bad)


def _cycle() -> list[str] | None:
    """One import circle among the package's modules, or ``None``."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in GRAPH.get(node, ()):
            if nxt == node or nxt not in GRAPH:
                continue
            # a package's __init__ importing its own submodules is not a circle
            if node.startswith(nxt + "."):
                continue
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        path.pop()
        state[node] = 2
        return None

    for start in GRAPH:
        if start not in state and (found := visit(start)):
            return found
    return None


def test_no_import_circles() -> None:
    cycle = _cycle()
    assert cycle is None, "import circle: " + " -> ".join(cycle or [])


def test_the_layer_check_can_fail() -> None:
    # an upward edge and a circle, in a made-up graph, are found by the same code
    saved = dict(GRAPH)
    try:
        GRAPH["openptrack_py.messages.codec"] = ["openptrack_py.tracking.tracker"]
        GRAPH["openptrack_py.tracking.tracker"] = ["openptrack_py.messages.codec"]
        assert _cycle() is not None
    finally:
        GRAPH.clear()
        GRAPH.update(saved)


@pytest.mark.parametrize("name", sorted(MODULES), ids=sorted(MODULES))
def test_no_file_too_long_without_a_reason(name: str) -> None:
    path = MODULES[name]
    text = path.read_text()
    lines = text.count("\n")
    if lines > MAX_FILE_LINES:
        doc = ast.get_docstring(ast.parse(text)) or ""
        assert LONG_FILE_REASON in doc, (
            f"{path.relative_to(PACKAGE.parent)} has {lines} lines (limit {MAX_FILE_LINES}): "
            f"split it, or say in its docstring why it is {LONG_FILE_REASON} ..."
        )


def test_no_function_too_long() -> None:
    long = []
    for path in MODULES.values():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                size = (node.end_lineno or node.lineno) - node.lineno + 1
                if size > MAX_FUNCTION_LINES:
                    long.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {node.name}")
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines:\n" + "\n".join(long)
