"""The import graph of our packages, drawn from the code (ast): an edge for every import of
one of our modules, at module level and inside functions alike, so a loop closed by a
deferred import is a cycle too (imports under `if TYPE_CHECKING:` never run: not edges).
`tests/test_import_graph.py` fails on any cycle.

    python -m tests.import_graph            # each module and what it imports
    python -m tests.import_graph --dot      # the same as Graphviz (| dot -Tsvg > graph.svg)
    python -m tests.import_graph --cycles   # each cycle, one line; exit 1 when there is one

Imports by name at run time (`importlib.import_module("...")`) are not seen.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections import deque
from collections.abc import Container, Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "signatures", "remoteid", "registry", "authn", "lab")

Graph = dict[str, set[str]]


def module_name(path: Path, root: Path = ROOT) -> str:
    """`authn/audit/writer.py` -> `authn.audit.writer`; a package's `__init__.py` -> the package."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _type_checking(node: ast.AST) -> bool:
    """`if TYPE_CHECKING:` (or `typing.TYPE_CHECKING`): a block only a type checker reads."""
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _run_time_nodes(tree: ast.AST) -> list[ast.AST]:
    """Every node that may run: all but the bodies of `if TYPE_CHECKING:` (their `else` runs)."""
    out: list[ast.AST] = []
    todo = [tree]
    while todo:
        node = todo.pop()
        out.append(node)
        if _type_checking(node):
            todo += node.orelse
            continue
        todo += list(ast.iter_child_nodes(node))
    return out


def _targets(path: Path, package: str) -> list[str]:
    """Every module name an import that runs in the file may mean (absolute, relative resolved);
    imports under `if TYPE_CHECKING:` never run, so they close no cycle."""
    out: list[str] = []
    for node in _run_time_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            out += [f"{base}.{a.name}" for a in node.names] + [base]
    return out


def build(root: Path = ROOT, packages: tuple[str, ...] = PACKAGES) -> Graph:
    """Module -> the modules of ours it imports (the longest existing prefix of each name)."""
    files = {module_name(p, root): p for pkg in packages for p in sorted((root / pkg).rglob("*.py"))}
    return {name: ours(_targets(path, _package_of(name, path)), files, name) for name, path in files.items()}


def _package_of(name: str, path: Path) -> str:
    """The package a relative import in the module starts from."""
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def ours(targets: Iterable[str], modules: Container[str], importer: str) -> set[str]:
    """The modules of ours that imported names mean: each name's longest prefix in `modules`,
    the importer itself left out."""
    found: set[str] = set()
    for target in targets:
        while target and target not in modules:
            target = target.rpartition(".")[0]
        if target and target != importer:
            found.add(target)
    return found


def components(graph: Graph) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, edges = work[-1]
            nxt = next(edges, None)
            if nxt is not None:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp: list[str] = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    comp.append(member)
                    if member == node:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
    return sorted(found)


def cycle_in(graph: Graph, component: list[str]) -> list[str]:
    """A shortest cycle through the component's first module: [a, b, ..., a]."""
    start, members = component[0], set(component)
    parent: dict[str, str] = {}
    queue = deque([start])
    while queue:
        node = queue.popleft()
        for nxt in sorted(graph[node] & members):
            if nxt == start:
                path = [node]
                while path[-1] != start:
                    path.append(parent[path[-1]])
                return [*reversed(path), start]
            if nxt not in parent:
                parent[nxt] = node
                queue.append(nxt)
    raise ValueError(f"{component} is not a cycle")


def cycles(graph: Graph) -> list[list[str]]:
    """One named cycle per strongly connected component (none: the graph is acyclic)."""
    return [cycle_in(graph, comp) for comp in components(graph)]


def dot(graph: Graph) -> str:
    """The graph in Graphviz's language, one cluster per top-level package."""
    lines = ["digraph imports {", "  rankdir=BT; node [shape=box, fontsize=10];"]
    for pkg in sorted({m.split(".")[0] for m in graph}):
        lines.append(f'  subgraph "cluster_{pkg}" {{ label="{pkg}";')
        lines += [f'    "{m}";' for m in sorted(graph) if m.split(".")[0] == pkg]
        lines.append("  }")
    lines += [f'  "{a}" -> "{b}";' for a in sorted(graph) for b in sorted(graph[a])]
    return "\n".join([*lines, "}"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.import_graph", description=__doc__.split("\n\n")[0])
    parser.add_argument("--dot", action="store_true", help="print Graphviz instead of one line per module")
    parser.add_argument("--cycles", action="store_true", help="print only the cycles; exit 1 when there is one")
    args = parser.parse_args(argv)
    graph = build()
    found = cycles(graph)
    if args.cycles:
        print("\n".join(" -> ".join(c) for c in found) or f"no cycle among {len(graph)} modules")
    elif args.dot:
        print(dot(graph))
    else:
        print("\n".join(f"{m}: {' '.join(sorted(graph[m]))}" for m in sorted(graph)))
    return 1 if found and args.cycles else 0


if __name__ == "__main__":
    sys.exit(main())
