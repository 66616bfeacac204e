"""No product function is longer than `MAX_LINES`: every function and method, nested ones
included, of the product packages (not the laboratory, tests or benchmarks), counted from its
`def` line to its last line (decorators excluded). A long function does several jobs: split it,
and where many parameters travel together, pass one frozen config object."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PRODUCT = ("core", "signatures", "remoteid", "registry", "authn")
MAX_LINES = 100


def _lengths(path: Path, root: Path = ROOT) -> list[tuple[str, int]]:
    """(path:qualified name, lines) of every function in `path`, methods and nested ones included."""
    rel = path.relative_to(root).as_posix()
    out: list[tuple[str, int]] = []

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = f"{prefix}{child.name}"
                out.append((f"{rel}:{name}", child.end_lineno - child.lineno + 1))
                walk(child, f"{name}.")
            elif isinstance(child, ast.ClassDef):
                walk(child, f"{prefix}{child.name}.")
            else:
                walk(child, prefix)

    walk(ast.parse(path.read_text(), str(path)), "")
    return out


def _all_lengths() -> dict[str, int]:
    return dict(item for pkg in PRODUCT for p in sorted((ROOT / pkg).rglob("*.py")) for item in _lengths(p))


def test_no_product_function_is_over_the_limit() -> None:
    long = {name: n for name, n in _all_lengths().items() if n > MAX_LINES}
    assert not long, "\n".join(f"{name}: {n} lines (at most {MAX_LINES})" for name, n in sorted(long.items()))


def test_the_walk_finds_methods_and_nested_functions(tmp_path: Path) -> None:
    def body(indent: int) -> str:
        return "\n".join(" " * indent + "x = 1" for _ in range(MAX_LINES))

    src = tmp_path / "probe.py"
    src.write_text(f"class A:\n    @property\n    def m(self):\n{body(8)}\n\n\n"
                   f"def f():\n    def g():\n{body(8)}\n")
    found = dict(_lengths(src, tmp_path))
    assert found["probe.py:A.m"] == MAX_LINES + 1  # the decorator not counted
    assert found["probe.py:f.g"] == MAX_LINES + 1
    assert found["probe.py:f"] == MAX_LINES + 2
