"""A digest of the code that computes something, for cache keys (docs/classifiers.md "Dataset cache key").

Version constants are bumped by hand, and a cache keyed on them alone is stale as soon as code
changes without a bump: a local experiment that is reverted, a change a golden scene does not
reach. `code_digest` hashes the code itself: every module of our packages that the roots import,
directly or lazily inside a function, transitively, as its syntax tree without docstrings. So a
comment, a docstring or a reformatting leaves the digest as it is, and any change to a statement
changes it. Standard-library and third-party modules are not followed (their versions are not
ours to track here).
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path

__all__ = ["code_digest", "modules_reached"]

#: Top-level packages whose modules are followed and hashed.
OUR_PACKAGES = ("signatures",)


def code_digest(roots: Iterable[str], packages: Iterable[str] = OUR_PACKAGES) -> str:
    """sha256 (hex, 16 characters) of the docstring-free syntax trees of
    `modules_reached(roots, packages)`. Cached per process: the source is read once."""
    return _digest(tuple(sorted(set(roots))), tuple(sorted(set(packages))))


@lru_cache(maxsize=32)
def _digest(roots: tuple[str, ...], packages: tuple[str, ...]) -> str:
    h = hashlib.sha256()
    for name, tree in sorted(_parsed(roots, frozenset(packages)).items()):
        h.update(name.encode() + b"\0" + ast.dump(_without_docstrings(tree)).encode() + b"\0")
    return h.hexdigest()[:16]


def modules_reached(roots: Iterable[str], packages: Iterable[str] = OUR_PACKAGES) -> list[str]:
    """The roots (any module with a source file) and every module of `packages` they import,
    transitively, sorted by name."""
    return sorted(_parsed(roots, frozenset(packages)))


def _parsed(roots: Iterable[str], ours: frozenset[str]) -> dict[str, ast.Module]:
    """Each module `modules_reached` names and its syntax tree, every source read and parsed once."""
    trees: dict[str, ast.Module] = {}
    stack = [r for r in roots if _source(r) is not None]
    while stack:
        name = stack.pop()
        if name not in trees:
            trees[name] = _tree(name)
            stack.extend(m for m in _imports(trees[name], ours) if m not in trees)
    return trees


def _source(name: str) -> Path | None:
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):  # a parent that is not a package, a bad name
        return None
    origin = getattr(spec, "origin", None) if spec else None
    return Path(origin) if origin and origin.endswith(".py") else None


def _tree(name: str) -> ast.Module:
    path = _source(name)
    if path is None:
        raise ValueError(f"{name}: no Python source to digest")
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def _imports(tree: ast.Module, ours: frozenset[str]) -> set[str]:
    """The modules of packages `ours` that a module's tree imports anywhere in its body (a
    package's submodules named in `from package import a, b` included)."""
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.split(".")[0] in ours)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                and node.module.split(".")[0] in ours:
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
    return {m for m in found if _source(m) is not None}


def _without_docstrings(tree: ast.Module) -> ast.Module:
    """The tree with the docstring of the module and of every class and function removed."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                node.body = body[1:] or [ast.Pass()]
    return tree
