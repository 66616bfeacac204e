"""Commands from other distributions (authn/cli/plugins.py): found through the `authn.plugins`
entry points of the installed distributions, as importlib.metadata finds them (a `*.dist-info`
folder with an `entry_points.txt` on the path), loaded only when asked for; the laboratory's
commands named with how to install it when it is not installed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PLUGIN = '''
import typer


def hello(name: str = typer.Option("world", "--name", help="Whom to greet.")) -> None:
    """Say hello (a plugin command).

    Example: authn hello --name you
    """
    typer.echo(f"hello {name}")


def extra() -> None:
    """A plugin command in the product's `features` group.

    Example: authn features extra
    """
    typer.echo("extra")


NOT_A_COMMAND = 3
'''

#: a probe that runs `authn` as if no plugin were installed (the laboratory included)
WITHOUT_PLUGINS = """
import sys
import authn.cli.plugins
authn.cli.plugins.installed = dict
from authn.cli import main
sys.exit(main(sys.argv[1:]))
"""

#: a probe that runs `authn`, then prints how often it scanned for plugins and which plugin modules it imported
COUNTING_SCANS = """
import sys
import authn.cli.plugins as p
scans = []
real = p.installed
p.installed = lambda: scans.append(1) or real()
from authn.cli import main
code = main(sys.argv[1:])
print(len(scans), sorted(m for m in sys.modules if m.startswith(("hello_plugin", "lab"))), file=sys.stderr)
"""


def _distribution(site: Path, name: str, entry_points: str) -> None:
    """A distribution as importlib.metadata discovers one: `<name>-<version>.dist-info` on the path."""
    info = site / f"{name}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(f"[authn.plugins]\n{entry_points}\n")


def _authn(args: list[str], site: Path | None = None, probe: str | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "COLUMNS": "100"}
    if site is not None:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(site), env.get("PYTHONPATH", "")) if p)
    cmd = [sys.executable, "-c", probe, *args] if probe else [sys.executable, "-m", "authn", *args]
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)


@pytest.fixture
def site(tmp_path: Path) -> Path:
    """A folder with one plugin distribution: `authn hello` and `authn features extra`."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "hello_plugin.py").write_text(PLUGIN)
    _distribution(site, "hello_plugin", "hello = hello_plugin:hello\nfeatures.extra = hello_plugin:extra\n")
    return site


def test_installed_plugins_are_listed_and_run(site: Path) -> None:
    top = _authn(["-h"], site)
    assert top.returncode == 0 and "hello" in top.stdout and "Say hello" in top.stdout, top.stdout
    assert "extra" in _authn(["features", "-h"], site).stdout
    run = _authn(["hello", "--name", "radar"], site)
    assert (run.returncode, run.stdout) == (0, "hello radar\n"), run.stderr
    assert _authn(["features", "extra"], site).stdout == "extra\n"
    assert "Example: authn hello --name you" in _authn(["hello", "-h"], site).stdout


def test_a_plugin_that_fails_to_load_is_one_line_exit_3(site: Path) -> None:
    """Invoked, or listed by help: one line naming the plugin and its distribution, exit 3 (a
    product command never looks, below)."""
    _distribution(site, "broken_plugin", "broken = no_such_module_anywhere:command")
    for args in (["broken"], ["-h"]):
        proc = _authn(args, site)
        assert proc.returncode == 3, (args, proc.stderr)
        assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
        assert "'broken' (broken_plugin 1.0) failed to load: ModuleNotFoundError" in proc.stderr, proc.stderr
    assert _authn(["hello"], site).stdout == "hello world\n"
    _distribution(site, "odd_plugin", "odd = hello_plugin:NOT_A_COMMAND")
    proc = _authn(["odd"], site)
    assert proc.returncode == 3 and proc.stderr == "error: plugin command 'odd' is a int, not a function\n", proc.stderr


def test_a_product_command_neither_scans_nor_loads_plugins(site: Path, tmp_path: Path) -> None:
    """`authn check` and every other product command: the installed distributions are not scanned
    for plugins and no plugin is imported, so a cold check pays nothing for them."""
    probe = COUNTING_SCANS
    db = ["--db", f"sqlite:///{tmp_path / 'r.sqlite3'}"]
    for args in (["registry", "list", "--json"], ["check", str(tmp_path / "missing.h5"), "--json"],
                 ["features", "show", str(tmp_path / "missing.h5")]):
        proc = _authn([*db, *args], site, probe)
        assert proc.stderr.strip().splitlines()[-1] == "0 []", (args, proc.stderr)
    proc = _authn([*db, "hello"], site, probe)  # the probe itself counts: one scan, one plugin imported
    assert proc.stderr.strip().splitlines()[-1] == "1 ['hello_plugin']", proc.stderr


@pytest.mark.parametrize(("command", "args"), [("bench", ["--quick"]), ("features accuracy", ["--n", "1"]),
                                             ("features score", ["truth.csv"])])
def test_the_lab_not_installed_says_how_to_install_it(command: str, args: list[str]) -> None:
    proc = _authn([*command.split(), *args], probe=WITHOUT_PLUGINS)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    assert proc.stderr.count("\n") == 1 and "pip install -e ./lab" in proc.stderr, proc.stderr
    assert f"`authn {command}` is in the laboratory (authn-lab), which is not installed" in proc.stderr
    as_json = _authn([*command.split(), *args, "--json"], probe=WITHOUT_PLUGINS)
    assert as_json.returncode == 2 and json.loads(as_json.stdout)["exit_code"] == 2, as_json.stdout


def test_without_the_lab_help_lists_only_the_product() -> None:
    proc = _authn(["-h"], probe=WITHOUT_PLUGINS)
    assert proc.returncode == 0 and " bench " not in proc.stdout and " check " in proc.stdout


def test_the_lab_distribution_registers_its_commands(tmp_path: Path) -> None:
    """lab/pyproject.toml's entry points, installed as a dist-info, give `authn bench` and
    `authn features accuracy|score` by real discovery (the lab's own code from this checkout)."""
    import tomllib

    lab = tomllib.loads((ROOT / "lab" / "pyproject.toml").read_text())
    points = lab["project"]["entry-points"]["authn.plugins"]
    assert set(points) == {"bench", "features.accuracy", "features.score"}
    assert "lab*" not in str(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"])
    packages = {".".join(("lab", *init.parent.relative_to(ROOT / "lab").parts))
                for init in (ROOT / "lab").rglob("__init__.py") if "build" not in init.relative_to(ROOT).parts}
    assert set(lab["tool"]["setuptools"]["packages"]) == packages  # every package of lab/ ships in authn-lab
    site = tmp_path / "site"
    _distribution(site, "authn_lab", "\n".join(f"{k} = {v}" for k, v in points.items()))
    assert "Benchmark decisions" in _authn(["bench", "-h"], site).stdout
    proc = _authn(["features", "accuracy", "--preset", "paper", "--snr", "20", "--n", "1", "--json"], site)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)[0]["preset"] == "paper"


def test_entry_point_names_are_command_paths() -> None:
    from importlib.metadata import EntryPoint

    from authn.cli.plugins import ENTRY_POINT_GROUP, by_path

    eps = [EntryPoint(name, f"m:{name.replace('.', '_')}", ENTRY_POINT_GROUP)
           for name in ("bench", "features.accuracy", "bench", ".bad")]
    table = by_path(eps)
    assert set(table) == {("bench",), ("features", "accuracy")}
    assert table[("bench",)] is eps[0]  # the first on the path wins
