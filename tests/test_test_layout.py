"""The benchmarks stand apart from the test suite: no file under benchmarks/ imports the
`tests` package (what both need lives in an importable package, e.g. lab/flash_gates.py)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def imports_of_tests(source: str) -> list[tuple[int, str]]:
    """(line, module) of each `import tests...` / `from tests... import`, inside functions too."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found += [(node.lineno, n) for n in names if n == "tests" or n.startswith("tests.")]
    return found


def test_benchmarks_do_not_import_the_tests_package() -> None:
    files = sorted((ROOT / "benchmarks").rglob("*.py"))
    assert files, "no benchmarks found"
    offenders = [f"{f.relative_to(ROOT)}:{line} imports {name}"
                 for f in files for line, name in imports_of_tests(f.read_text(encoding="utf-8"))]
    assert not offenders, "\n".join(offenders)


def test_the_check_sees_every_form_of_import() -> None:
    source = ("import tests\nimport numpy, tests.conftest as c\nfrom tests.features import conftest\n"
              "def f():\n    from tests import x\nfrom testsuite import y\nfrom lab import tests\n")
    assert imports_of_tests(source) == [(1, "tests"), (2, "tests.conftest"), (3, "tests.features"), (5, "tests")]
