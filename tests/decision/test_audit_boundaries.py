"""The audit package's boundaries: no module imports another module's underscore name (what the
modules share lives in authn/audit/_internal), nothing outside the package reaches into
_internal, the public API names no private name, and the product records through AuditLog
instead of building entries itself."""

from __future__ import annotations

import ast
from pathlib import Path

import authn.audit

ROOT = Path(__file__).resolve().parents[2]
AUDIT = ROOT / "authn" / "audit"
PRODUCT = ("authn", "core", "registry", "remoteid", "signatures", "lab")


def _imports(path: Path) -> list[tuple[str, list[str], int]]:
    """(module, names, line) of every `from X import ...` in a file, relative imports resolved."""
    package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level else ""
            module = ".".join(p for p in (base, node.module or "") if p)
            out.append((module, [a.name for a in node.names], node.lineno))
        elif isinstance(node, ast.Import):
            out += [(a.name, [], node.lineno) for a in node.names]
    return out


def test_no_audit_module_imports_another_modules_private_name() -> None:
    bad = []
    for path in sorted(AUDIT.rglob("*.py")):
        for module, names, line in _imports(path):
            if module.startswith("authn.audit"):
                bad += [f"{path.relative_to(ROOT)}:{line}: {module}.{n}" for n in names if n.startswith("_")
                        and not n.startswith("__")]
    assert not bad, "private names imported across audit modules (move them to authn/audit/_internal):\n" + \
        "\n".join(bad)


def test_nothing_outside_the_audit_package_imports_its_internals() -> None:
    bad = []
    for top in PRODUCT:
        for path in sorted((ROOT / top).rglob("*.py")):
            if AUDIT in path.parents:
                continue
            for module, names, line in _imports(path):
                if module.startswith("authn.audit._internal") or \
                        (module == "authn.audit" and any(n.startswith("_") for n in names)):
                    bad.append(f"{path.relative_to(ROOT)}:{line}: {module}")
    assert not bad, "\n".join(bad)


def test_the_public_api_names_no_private_name() -> None:
    assert not [n for n in authn.audit.__all__ if n.startswith("_")]
    assert "_iso_db" not in authn.audit.__all__


def test_the_product_records_through_audit_log() -> None:
    """Only authn.audit builds a NewEntry or calls the writer: every other caller goes through AuditLog."""
    bad = []
    for top in PRODUCT:
        for path in sorted((ROOT / top).rglob("*.py")):
            if AUDIT in path.parents:
                continue
            tree = ast.parse(path.read_text())
            bad += [f"{path.relative_to(ROOT)}:{node.lineno}: builds a NewEntry" for node in ast.walk(tree)
                    if isinstance(node, ast.Call) and "NewEntry" in (getattr(node.func, "id", None),
                                                                      getattr(node.func, "attr", None))]
            bad += [f"{path.relative_to(ROOT)}:{line}: imports the writer's append" for module, names, line
                    in _imports(path) if module.startswith("authn.audit") and "append" in names]
    assert not bad, "\n".join(bad)


def test_type_checkers_see_what_the_package_loads_lazily() -> None:
    """`authn.audit.__getattr__` loads each public name from its module (`_WHERE`); the
    `TYPE_CHECKING` imports say the same, so a type checker sees each name's real type."""
    tree = ast.parse((AUDIT / "__init__.py").read_text())
    guarded = next(n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test) == "TYPE_CHECKING")
    seen = {n.module.removeprefix("authn.audit."): tuple(sorted(a.name for a in n.names))
            for n in guarded.body if isinstance(n, ast.ImportFrom) and n.module}
    assert seen == {m: tuple(sorted(names)) for m, names in authn.audit._WHERE.items()}
