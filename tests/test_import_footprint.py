"""A check needs only the product: training, plotting and the laboratory stay out of its
process (they are pyproject extras), and a command that needs a missing extra names it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from core.errors import describe

OPTIONAL = ("sklearn", "onnx", "matplotlib", "torch", "dask", "distributed", "locust", "lab")
#: rich's help rendering (typer.rich_utils pulls these): only a command's help needs them
HELP_ONLY = ("pygments", "markdown_it")
#: installed and used elsewhere (the service, the registry's import, the simulator's scenes), but ~90 ms
#: of a cold check: the types a check builds are `core.checked` dataclasses (and typer < 0.26)
NOT_ON_CHECK = ("pydantic", "pydantic_core", "annotated_types", "typing_inspection")
#: the WGS-84 conversion is `authn.geodesy`: pymap3d's time conversions pull in dateutil (~9 ms)
GEODESY = ("pymap3d", "dateutil")
#: the human output is plain text on a pipe (`authn.cli.plaintext`): rich only on a terminal (~20 ms)
HUMAN_ON_A_PIPE = ("rich",)
#: package data is read as files beside the modules (importlib.resources and its readers cost ~5 ms)
PACKAGE_DATA = ("importlib.resources", "importlib.readers")
#: what only an encoder or a long dwell's rotor-line search needs (`decimal`; `statistics`, ~5 ms)
NOT_ON_A_PAPER_CHECK = ("decimal", "statistics")
#: what only an option of `check` needs: --trust-registry (the UA keys), --claims (a CSV)
ONLY_WITH_THEIR_OPTION = ("authn.uakeys", "csv")
#: the command modules a check does not run (`authn.cli.lazy`: each imported when its command is)
OTHER_COMMANDS = tuple(f"authn.cli.{m}" for m in ("audit", "db", "demo", "features", "importer", "inspect", "keys",
                                                   "models", "plot", "registry", "rid", "serve", "simulate"))

PROBE = """
import json, sys
from authn.cli import main
code = main(sys.argv[1:])
pst = vars(sys.modules.get("cedarpy.pst", sys))  # loaded, or the stand-in of authn.cedarpy_tree
print(json.dumps({"code": code, "modules": sorted(sys.modules), "policy_tree": "PolicySet" in pst}), file=sys.stderr)
"""


def _check(tmp_path: Path, *options: str) -> tuple[dict, str]:
    """A cold `authn check` of a genuine m300 return, piped: (its exit code and every module it
    imported, its stdout)."""
    from authn.demo import register_examples
    from tests.flights import write_m300_flight

    url = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(url)
    genuine = write_m300_flight(tmp_path)
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "TTY_COMPATIBLE")}
    proc = subprocess.run([sys.executable, "-c", PROBE, "--db", url, "check", str(genuine), *options],
                          capture_output=True, text=True, timeout=120, env=env)
    return json.loads(proc.stderr.strip().splitlines()[-1]), proc.stdout


def _loaded(modules: list[str], forbidden: tuple[str, ...]) -> list[str]:
    """The forbidden modules (a package: it or any module in it) among those imported."""
    return sorted(f for f in forbidden if any(m == f or m.startswith(f + ".") for m in modules))


def test_a_check_imports_no_optional_dependency(tmp_path: Path) -> None:
    report, out = _check(tmp_path, "--json")
    assert report["code"] == 4, report  # the whole radar path ran: one unsigned dwell is inconclusive
    assert json.loads(out)["decision"] == "inconclusive"
    loaded = _loaded(report["modules"], OPTIONAL + HELP_ONLY + NOT_ON_CHECK + GEODESY + OTHER_COMMANDS + PACKAGE_DATA
                     + NOT_ON_A_PAPER_CHECK + ONLY_WITH_THEIR_OPTION)
    assert not loaded, f"a check imported {loaded}"
    assert not report["policy_tree"], "a check imported cedarpy.pst (deciding never reads it)"
    assert "onnxruntime" in report["modules"] or "numpy" in report["modules"]


def test_the_human_output_on_a_pipe_imports_no_rich(tmp_path: Path) -> None:
    report, out = _check(tmp_path)
    assert report["code"] == 4 and out.startswith("INCONCLUSIVE 1581BDEM00000002"), out
    loaded = _loaded(report["modules"], OPTIONAL + HELP_ONLY + NOT_ON_CHECK + GEODESY + OTHER_COMMANDS
                     + HUMAN_ON_A_PIPE)
    assert not loaded, f"a check imported {loaded}"


def test_a_missing_extra_is_named() -> None:
    exc = ModuleNotFoundError("No module named 'sklearn'", name="sklearn")
    line = describe(exc)
    assert "'train'" in line and "pip install 'uav-radar-authn[train]'" in line
    assert describe(ModuleNotFoundError("x", name="matplotlib.pyplot")).count("[plot]") == 1
    assert describe(ModuleNotFoundError("x", name="numpy")).startswith("internal error")
