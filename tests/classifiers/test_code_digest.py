"""`signatures.train.code_digest`: a cache key that follows the code, not its comments or docstrings."""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import pytest

from signatures.train.code_digest import code_digest, modules_reached


@pytest.fixture
def package(tmp_path: Path, monkeypatch):
    """A throw-away package `dg_pkg` on sys.path: `root` imports `helper` lazily, inside a function,
    and numpy at the top (not followed)."""
    pkg = tmp_path / "dg_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "root.py").write_text(textwrap.dedent('''
        """Root."""
        import numpy as np


        def f(x):
            """Doubles."""
            from dg_pkg import helper
            return helper.g(x) * 2  # a comment
    '''))
    (pkg / "helper.py").write_text("def g(x):\n    return x + 1\n")
    (pkg / "unused.py").write_text("def h():\n    return 0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield pkg
    for name in [m for m in sys.modules if m.startswith("dg_pkg")]:
        del sys.modules[name]


def _digest(package: Path) -> str:
    from signatures.train import code_digest as module

    module._digest.cache_clear()  # the files change under the same names within one process
    return code_digest(["dg_pkg.root"], packages=["dg_pkg"])


def test_follows_lazy_imports_of_our_packages_only(package) -> None:
    assert modules_reached(["dg_pkg.root"], packages=["dg_pkg"]) == ["dg_pkg", "dg_pkg.helper", "dg_pkg.root"]


def test_comments_docstrings_and_layout_do_not_count(package) -> None:
    base = _digest(package)
    root = package / "root.py"
    text = root.read_text()
    root.write_text(text.replace('"""Doubles."""', '"""Doubles x, via helper."""')
                    .replace("# a comment", "# another").replace("import numpy as np", "import numpy as np\n\n"))
    (package / "unused.py").write_text("def h():\n    return 1\n")  # not imported by the root
    assert _digest(package) == base


@pytest.mark.parametrize("edit", [("root.py", "* 2", "* 3"), ("helper.py", "x + 1", "x + 2")])
def test_a_changed_statement_changes_it(package, edit) -> None:
    base = _digest(package)
    name, old, new = edit
    path = package / name
    path.write_text(path.read_text().replace(old, new))
    assert _digest(package) != base


def test_shipped_featurizer_digest_is_stable_within_a_process() -> None:
    roots = ["signatures.features", "signatures.sim.simulate"]
    assert code_digest(roots) == code_digest(list(reversed(roots)))
