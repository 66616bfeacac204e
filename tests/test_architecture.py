"""The layers of docs/architecture.md hold: every import between our packages, at module
level or inside a function, goes down (or stays within a layer); cycles are
tests/test_import_graph.py's, which finds them through imports inside functions too. The
laboratory (`lab`, the authn-lab distribution) sits above the whole product, its command line
included: the product never imports it, not even by name through importlib (its commands
reach `authn` as entry-point plugins)."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.import_graph import PACKAGES, ROOT, module_name, ours


#: bottom to top; a module belongs to the longest prefix listed
LAYERS = (
    ("core",),                      # errors, exit codes, shared parsing, untrusted-text escaping
    ("signatures", "remoteid"),     # radar: returns, features, classifiers, simulator; Remote ID codec, DRIP
    ("registry",),                  # storage (models, migrations, db) and the registry
    ("authn",),                     # decision, audit, service, cluster
    ("authn.cli", "authn.__main__"),  # the command line, composing all of the above
    ("lab",),                       # authn-lab: benchmarks, the held-out world, accuracy runs, their commands
)
#: the product: every package of the uav-radar-authn distribution
PRODUCT = ("core", "signatures", "remoteid", "registry", "authn")


def _modules() -> dict[str, Path]:
    return {module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def _imports(path: Path, module_level: bool) -> list[str]:
    return _imports_in(ast.parse(path.read_text()), module_level)


def _imports_in(tree: ast.Module, module_level: bool) -> list[str]:
    """The modules `tree` imports: import statements, and (all levels only) the literal name
    given to `importlib.import_module` or `__import__`."""
    nodes = tree.body if module_level else ast.walk(tree)
    out: list[str] = []
    for node in nodes:
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out += [f"{node.module}.{a.name}" for a in node.names] + [node.module]
        elif isinstance(node, ast.Call) and _is_dynamic_import(node.func) and node.args \
                and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
            out.append(node.args[0].value)
    return out


def _is_dynamic_import(func: ast.expr) -> bool:
    return (isinstance(func, ast.Name) and func.id in ("__import__", "import_module")) or \
        (isinstance(func, ast.Attribute) and func.attr == "import_module")


def _graph(module_level: bool = True) -> dict[str, set[str]]:
    modules = _modules()
    return {name: ours(_imports(path, module_level), modules, name) for name, path in modules.items()}


def layer_of(module: str) -> int:
    best, level = -1, -1
    for i, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best:
                best, level = len(p), i
    return level


def test_every_module_has_a_layer() -> None:
    assert all(layer_of(m) >= 0 for m in _modules())


def test_imports_only_go_down_inside_functions_too() -> None:
    graph = _graph(module_level=False)
    assert sum(len(v) for v in graph.values()) > 300
    up = sorted(f"{a} -> {b}" for a, targets in graph.items() for b in targets if layer_of(b) > layer_of(a))
    assert not up, "imports that go up a layer:\n" + "\n".join(up)


def test_layer_check_finds_a_planted_upward_import() -> None:
    assert layer_of("registry.store") < layer_of("authn.check") < layer_of("authn.cli.check") < layer_of("lab.bench")
    assert layer_of("lab.cli.bench") == layer_of("lab") and layer_of("core.errors") == 0


def _lab_imports(modules: dict[str, Path]) -> list[str]:
    return sorted(f"{name} -> {target}" for name, path in modules.items()
                  if name.split(".")[0] in PRODUCT
                  for target in _imports(path, module_level=False) if target.split(".")[0] == "lab")


def test_the_product_never_imports_the_lab() -> None:
    """No module of the product imports `lab`, at module level, inside a function or by name."""
    modules = _modules()
    assert sum(1 for m in modules if m.split(".")[0] in PRODUCT) > 100
    assert not (found := _lab_imports(modules)), "the product imports the laboratory:\n" + "\n".join(found)


def test_lab_import_check_finds_planted_imports(tmp_path: Path) -> None:
    """Each way of importing the lab is caught: at module level, in a function, through importlib."""
    for source in ("import lab.bench\n", "def f():\n    from lab.bench.tables import batch_table\n",
                   "def f():\n    import importlib\n    return importlib.import_module('lab.cli.bench')\n"):
        planted = tmp_path / "planted.py"
        planted.write_text(source)
        found = _lab_imports({"authn.cli.planted": planted})
        assert found and all(line.startswith("authn.cli.planted -> lab.") for line in found), (source, found)
    assert _lab_imports({"lab.cli.planted": planted}) == []  # the lab may import itself


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
