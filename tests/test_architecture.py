"""The layers of docs/architecture.md hold: every import between our packages, at module
level or inside a function, goes down (or stays within a layer), and the module-level
graph has no cycles (imports inside functions are deferred on purpose: they may close a
loop within a layer, never cross upwards)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "signatures", "remoteid", "registry", "authn", "lab")

#: bottom to top; a module belongs to the longest prefix listed
LAYERS = (
    ("core",),                      # errors, exit codes, shared parsing, untrusted-text escaping
    ("signatures", "remoteid"),     # radar: returns, features, classifiers, simulator; Remote ID codec, DRIP
    ("registry",),                  # storage (models, migrations, db) and the registry
    ("authn",),                     # decision, audit, service, cluster
    ("lab",),                       # benchmarks, the held-out world, accuracy runs
    ("authn.cli", "authn.__main__"),  # the command line, composing all of the above
)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def _imports(path: Path, module_level: bool) -> list[str]:
    tree = ast.parse(path.read_text())
    nodes = tree.body if module_level else ast.walk(tree)
    out: list[str] = []
    for node in nodes:
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out += [f"{node.module}.{a.name}" for a in node.names] + [node.module]
    return out


def _graph(module_level: bool = True) -> dict[str, set[str]]:
    modules = _modules()
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for name, path in modules.items():
        for target in _imports(path, module_level):
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name:
                graph[name].add(target)
    return graph


def layer_of(module: str) -> int:
    best, level = -1, -1
    for i, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best:
                best, level = len(p), i
    return level


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_every_module_has_a_layer() -> None:
    assert all(layer_of(m) >= 0 for m in _modules())


def test_imports_only_go_down_inside_functions_too() -> None:
    graph = _graph(module_level=False)
    assert sum(len(v) for v in graph.values()) > 300
    up = sorted(f"{a} -> {b}" for a, targets in graph.items() for b in targets if layer_of(b) > layer_of(a))
    assert not up, "imports that go up a layer:\n" + "\n".join(up)


def test_layer_check_finds_a_planted_upward_import() -> None:
    assert layer_of("registry.store") < layer_of("authn.check") < layer_of("lab.bench") < layer_of("authn.cli.check")
    assert layer_of("core.errors") == 0


def test_no_import_cycles() -> None:
    graph = _graph()
    assert len(graph) > 50
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


def test_cycle_detection_finds_a_planted_cycle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}
    assert _cycle(graph) == ["a", "b", "c", "a"]


def test_cli_modules_do_not_import_the_cli_package() -> None:
    """Commands are composed in authn/cli/__init__.py; no command module reaches back into it."""
    graph = _graph()
    back = sorted(m for m in graph if m.startswith("authn.cli.") and "authn.cli" in graph[m])
    assert not back, back


def _product_sources() -> dict[str, str]:
    """Module name -> source, for the product (everything below the laboratory)."""
    return {m: p.read_text() for m, p in _modules().items() if not (m == "lab" or m.startswith("lab."))}


def test_one_pem_parser() -> None:
    """Ed25519 PEM keys are parsed by `cryptography` in core/pem.py only: no other module calls
    its PEM loaders or takes a SubjectPublicKeyInfo apart by hand."""
    marks = ("load_pem_", "302a300506032b6570032100", "b64decode(b\"\".join")
    others = sorted(f"{m}: {mark}" for m, text in _product_sources().items() if m != "core.pem"
                    for mark in marks if mark in text)
    assert not others, others
