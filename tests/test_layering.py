"""The package boundaries of ``docs/design.md`` §1, read from the code.

Every ``import`` and ``from ... import`` in ``egs_bench/`` counts: at module level, inside
functions and under ``if TYPE_CHECKING:``, relative imports resolved. An import deferred into a
function still makes its module depend on the other one, so it cannot hide a cycle.

The allowed direction comes from the layer table in design.md §1, which this test parses: the
prose and the check are the same table.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
PACKAGE_DIR = REPO_ROOT / "egs_bench"
DESIGN = REPO_ROOT / "docs" / "design.md"
PACKAGE = "egs_bench"
#: how the layer table names the package's own ``__init__.py``
PACKAGE_INIT = "__init__"


@dataclass(frozen=True)
class ImportEdge:
    """``importer`` imports ``imported`` (both dotted module names) at ``line``."""

    importer: str
    imported: str
    line: int


def module_files(package_dir: Path = PACKAGE_DIR) -> dict[str, Path]:
    """Every module of the package by dotted name; a package is named by its folder."""
    modules: dict[str, Path] = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = list(path.relative_to(package_dir.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


def _imported_modules(node: ast.Import | ast.ImportFrom, module: str, is_package: bool,
                      modules: dict[str, Path]) -> list[str]:
    """The dotted names of the modules an import statement loads, relative imports resolved:
    ``from a import b`` loads the submodule ``a.b`` when there is one, else ``a``."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[:len(base) - (node.level - 1)]
        source = ".".join(base + ([node.module] if node.module else []))
    else:
        source = node.module or ""
    return [f"{source}.{alias.name}" if f"{source}.{alias.name}" in modules else source
            for alias in node.names]


def import_edges(modules: dict[str, Path]) -> list[ImportEdge]:
    """Every import of one package module by another (self-imports left out); a name that is
    not a module counts as its nearest enclosing package or module."""
    edges: list[ImportEdge] = []
    for module, path in modules.items():
        is_package = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if not isinstance(node, ast.Import | ast.ImportFrom):
                continue
            for name in _imported_modules(node, module, is_package, modules):
                while name not in modules and "." in name:
                    name = name.rsplit(".", 1)[0]
                if name in modules and name != module:
                    edges.append(ImportEdge(module, name, node.lineno))
    return edges


def find_cycles(modules: list[str], edges: list[ImportEdge]) -> list[list[str]]:
    """One cycle (``[a, b, ..., a]``) through each strongly connected group of modules
    (Tarjan's algorithm, iterative), shortest-first search inside each group."""
    graph: dict[str, list[str]] = {m: [] for m in modules}
    for edge in edges:
        if edge.imported not in graph[edge.importer]:
            graph[edge.importer].append(edge.imported)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []
    for root in modules:
        if root in index:
            continue
        work: list[tuple[str, int]] = [(root, 0)]
        while work:
            node, child = work.pop()
            if child == 0:
                index[node] = low[node] = len(index)
                stack.append(node)
                on_stack.add(node)
            if child < len(graph[node]):
                work.append((node, child + 1))
                nxt = graph[node][child]
                if nxt not in index:
                    work.append((nxt, 0))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            if low[node] == index[node]:
                group = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    group.append(member)
                    if member == node:
                        break
                if len(group) > 1:
                    groups.append(sorted(group))
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
    return [_shortest_cycle(sorted(group)[0], set(group), graph) for group in groups]


def _shortest_cycle(start: str, group: set[str], graph: dict[str, list[str]]) -> list[str]:
    """The shortest path from ``start`` back to itself inside ``group`` (breadth first)."""
    previous: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for nxt in graph[node]:
                if nxt not in group:
                    continue
                if nxt == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(previous[path[-1]])
                    return [start] + path[::-1][1:] + [start]
                if nxt not in previous:
                    previous[nxt] = node
                    following.append(nxt)
        frontier = following
    raise AssertionError(f"{start} is in a strongly connected group but on no cycle")


def layer_table(design: Path = DESIGN) -> dict[str, int]:
    """design.md §1's layer table: each package or top-level module (as the table names it,
    ``__init__`` for the package's own) and its layer number."""
    text = design.read_text(encoding="utf-8")
    section = re.search(r"^## 1\..*?(?=^## 2\.)", text, re.S | re.M)
    assert section, f"{design} has no section '## 1.'"
    layers: dict[str, int] = {}
    for row in re.findall(r"^\|\s*(\d+)\s*\|([^|]*)\|", section.group(0), re.M):
        for name in re.findall(r"`([^`]+)`", row[1]):
            unit = name.removesuffix("/").removesuffix(".py")
            assert unit not in layers, f"{unit} is listed twice in the layer table"
            layers[unit] = int(row[0])
    assert layers, f"{design} §1 has no layer table (rows '| <layer> | `name` ... |')"
    return layers


def unit_of(module: str) -> str:
    """The layer table's name for a module: its top-level package or base module."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else PACKAGE_INIT


def layer_violations(edges: list[ImportEdge], layers: dict[str, int],
                     files: dict[str, Path]) -> list[str]:
    """Imports against the layer table: a module may import its own package, any lower layer,
    and, in layer 0 (the base modules), the other base modules."""
    bad = []
    for edge in edges:
        importer, imported = unit_of(edge.importer), unit_of(edge.imported)
        if importer == imported:
            continue
        low, high = layers[imported], layers[importer]
        if low < high or low == high == 0:
            continue
        where = files[edge.importer].relative_to(REPO_ROOT)
        bad.append(f"{where}:{edge.line}: {edge.importer} (layer {high}) imports "
                   f"{edge.imported} (layer {low})")
    return bad


def test_the_import_reader_sees_deferred_relative_and_from_imports(tmp_path: Path) -> None:
    pkg = tmp_path / "egs_bench"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "base.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from .leaf import VALUE\n")
    (pkg / "sub" / "leaf.py").write_text(
        "def later():\n    from egs_bench import base\n    import egs_bench.sub.other\n")
    (pkg / "sub" / "other.py").write_text("from ..base import NAME\nfrom . import leaf\n")
    files = module_files(pkg)
    edges = {(e.importer, e.imported) for e in import_edges(files)}
    assert edges == {("egs_bench.sub", "egs_bench.sub.leaf"),
                     ("egs_bench.sub.leaf", "egs_bench.base"),
                     ("egs_bench.sub.leaf", "egs_bench.sub.other"),
                     ("egs_bench.sub.other", "egs_bench.base"),
                     ("egs_bench.sub.other", "egs_bench.sub.leaf")}
    assert find_cycles(sorted(files), import_edges(files)) == [
        ["egs_bench.sub.leaf", "egs_bench.sub.other", "egs_bench.sub.leaf"]]


def test_every_module_is_placed_in_the_layer_table() -> None:
    layers = layer_table()
    unplaced = sorted({unit_of(m) for m in module_files()} - set(layers))
    assert not unplaced, f"not in docs/design.md §1's layer table: {unplaced}"
    unknown = sorted(set(layers) - {unit_of(m) for m in module_files()})
    assert not unknown, f"the layer table names what egs_bench/ does not have: {unknown}"


def test_no_import_cycles() -> None:
    files = module_files()
    cycles = find_cycles(sorted(files), import_edges(files))
    assert not cycles, "import cycles (imports inside functions count):\n" + "\n".join(
        " -> ".join(cycle) for cycle in cycles)


def test_imports_follow_the_layer_table() -> None:
    files = module_files()
    bad = layer_violations(import_edges(files), layer_table(), files)
    assert not bad, "imports against docs/design.md §1's layer table:\n" + "\n".join(bad)
