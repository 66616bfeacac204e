"""No pytest run in this repository writes into the developer's home: the root conftest.py
points HOME, the XDG directories, MPLCONFIGDIR and the AUTHN_* paths at a temporary folder for
the whole session, before anything computes a default path, whichever folder or file pytest
is given. Proved here by child pytests whose HOME is a fresh empty folder and whose environment
has no XDG_*/AUTHN_* variables: a few test files (the CLI with its defaults, `authn demo`, the
audit log and its key), and a benchmark alone (`pytest benchmarks/...` does not load
tests/conftest.py); the folder is still empty afterwards."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: What the child pytest runs: the probes below and two quick files that drive the CLI and
#: the audit log (key, signed heads) through `authn.cli.main`.
CHILD_TESTS = [f"{Path(__file__).relative_to(ROOT)}::test_default_paths_point_into_the_session_folder",
               f"{Path(__file__).relative_to(ROOT)}::test_cli_with_its_defaults_stays_in_the_session_folder",
               "tests/registry/test_registry_cli.py", "tests/test_untrusted_input.py"]


#: A quick benchmark that writes the audit log key and signed heads to their default paths.
BENCHMARK = "benchmarks/test_bench_decision.py::test_audit_append_one_transaction"


def _pinned_root() -> Path:
    return Path(os.environ["AUTHN_TEST_SESSION_ROOT"])  # set by the root conftest.py


def _child_pytest(tmp_path: Path, *args: str) -> list[str]:
    """Run pytest on `args` in a child process with an empty HOME and none of the session's
    variables; what it left in that HOME."""
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("XDG_", "AUTHN_", "PYTEST_")) and k not in ("MPLCONFIGDIR", "PGPASSFILE")}
    env.update(HOME=str(home), AUTHN_TEST_CHILD="1")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-x",
                           f"--basetemp={tmp_path / 'child-tmp'}", *args],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    return sorted(str(p.relative_to(home)) for p in home.rglob("*"))


def test_default_paths_point_into_the_session_folder(tmp_path_factory) -> None:
    """Every default path is in the session folder, or in pytest's temporary folder (the log
    key and user models, which fixtures of tests/conftest.py set per test)."""
    import matplotlib
    import platformdirs

    from authn.audit.logkey import key_path
    from registry.urls import default_url, resolve_url
    from signatures.train.dataset import cache_dir

    root = _pinned_root()
    paths = {"HOME": Path.home(), "user_data_dir": platformdirs.user_data_dir("authn"),
             "user_cache_dir": platformdirs.user_cache_dir("authn"),
             "user_config_dir": platformdirs.user_config_dir("authn"),
             "user_state_dir": platformdirs.user_state_dir("authn"), "log key": key_path(None),
             "default database": default_url().removeprefix("sqlite:///"),
             "database": resolve_url(None).removeprefix("sqlite:///"),
             "user models": os.environ["AUTHN_MODELS_DIR"], "matplotlib": matplotlib.get_configdir()}
    if "AUTHN_CACHE_DIR" not in os.environ or os.environ["AUTHN_CACHE_DIR"].startswith(str(root)):
        paths["dataset cache"] = cache_dir()
    allowed = (root.resolve(), tmp_path_factory.getbasetemp().resolve())
    outside = {k: str(v) for k, v in paths.items() if not any(Path(v).resolve().is_relative_to(a) for a in allowed)}
    assert not outside, f"outside the session folder {root} and {allowed[1]}: {outside}"
    assert Path.home().resolve().is_relative_to(root.resolve())


def test_cli_with_its_defaults_stays_in_the_session_folder(tmp_path: Path) -> None:
    """`authn demo` (default database, demo folder in the user cache dir, log key) and
    `authn audit verify` in subprocesses, which inherit the session's environment."""
    for argv in (["demo"], ["audit", "verify"]):
        proc = subprocess.run([sys.executable, "-m", "authn", *argv], capture_output=True, text=True,
                              timeout=120, cwd=tmp_path)
        assert proc.returncode == 0, (argv, proc.stdout[-2000:], proc.stderr[-2000:])
    root = _pinned_root().resolve()
    assert any(root.rglob("registry.sqlite3")) and any(root.rglob("*.h5"))


@pytest.mark.slow  # ~11 s: a child pytest
def test_an_empty_home_stays_empty(tmp_path: Path) -> None:
    left = _child_pytest(tmp_path, *CHILD_TESTS)
    assert left == [], f"the tests wrote into HOME: {left[:20]}"


def test_a_benchmark_run_alone_leaves_home_empty(tmp_path: Path) -> None:
    """`pytest benchmarks/...` by itself (~4 s): the audit append writes its key and heads into
    the session folder, not into HOME/.local/share/authn."""
    left = _child_pytest(tmp_path, BENCHMARK)
    assert left == [], f"the benchmark wrote into HOME: {left[:20]}"
