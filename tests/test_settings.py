"""Every AUTHN_* variable is read by core/settings.py only, at call time, and listed once in
docs/architecture.md."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from core import settings
from core.errors import BadInput

ROOT = Path(__file__).resolve().parents[1]
PRODUCT = ("core", "signatures", "remoteid", "registry", "authn")
#: variables of the test harness, not of the product (tests/conftest.py, conftest.py)
TEST_ONLY = {"AUTHN_TEST_POSTGRES_URL", "AUTHN_TEST_SESSION_ROOT", "AUTHN_FUZZ_EXAMPLES"}


def _env_reads(path: Path) -> list[str]:
    """Where a module reads an AUTHN_* variable itself: a line naming both the environment and
    an AUTHN_ name, a typer `envvar="AUTHN_..."`, or a constant holding an AUTHN_ name (the
    indirection `os.environ.get(ENV_X)` goes through)."""
    text = path.read_text()
    out = [f"{path.name}:{n}" for n, line in enumerate(text.splitlines(), 1)
           if "AUTHN_" in line and re.search(r"\benviron\b|\bgetenv\b", line)]
    for node in ast.walk(ast.parse(text)):
        values = [k.value for k in node.keywords if k.arg == "envvar"] if isinstance(node, ast.Call) else \
            [node.value] if isinstance(node, ast.Assign) else []
        out += [f"{path.name}:{node.lineno}" for v in values
                if isinstance(v, ast.Constant) and isinstance(v.value, str) and v.value.startswith("AUTHN_")]
    return out


def test_no_product_module_but_core_settings_reads_an_authn_variable() -> None:
    files = [p for pkg in PRODUCT for p in sorted((ROOT / pkg).rglob("*.py"))]
    assert len(files) > 100
    readers = sorted(f"{p.parent.relative_to(ROOT)}/{hit}" for p in files if p != ROOT / "core" / "settings.py"
                     for hit in _env_reads(p))
    assert not readers, readers


def test_the_check_finds_each_way_of_reading(tmp_path: Path) -> None:
    snippets = ('x = os.environ.get("AUTHN_FFT")\n', 'ENV_KEY = "AUTHN_LOG_KEY"\n',
                'o = typer.Option(None, envvar="AUTHN_DATABASE_URL")\n', 'y = os.getenv("AUTHN_X", "1")\n')
    for i, code in enumerate(snippets):
        path = tmp_path / f"probe_{i}.py"
        path.write_text(code)
        assert _env_reads(path) == [f"{path.name}:1"], code


def test_one_field_per_variable() -> None:
    fields = list(settings.Settings._fields)
    assert fields == [v.field for v in settings.VARIABLES]
    assert len({v.name for v in settings.VARIABLES}) == len(fields)
    assert all(v.name.startswith("AUTHN_") and v.doc and v.default for v in settings.VARIABLES)


def test_values_are_read_when_asked_not_at_import(monkeypatch: pytest.MonkeyPatch) -> None:
    from signatures.dsp import fft

    monkeypatch.setenv("AUTHN_FFT", "scipy")
    assert fft.backend() == fft.resolve(None) == "scipy"
    monkeypatch.setenv("AUTHN_FFT", "")
    assert fft.backend() == "numpy"
    monkeypatch.setenv("AUTHN_AUDIT_CHECKPOINT_SECONDS", "2.5")
    assert settings.current().audit_checkpoint_seconds == 2.5


@pytest.mark.parametrize(("name", "value", "message"), [
    ("AUTHN_AUDIT_CHECKPOINT_EVERY", "ten", "$AUTHN_AUDIT_CHECKPOINT_EVERY: not a number: 'ten'"),
    ("AUTHN_AUDIT_CHECKPOINT_SECONDS", "0", "$AUTHN_AUDIT_CHECKPOINT_SECONDS: must be positive, got '0'"),
    ("AUTHN_AUDIT_APPEND_CHECK", "some", "$AUTHN_AUDIT_APPEND_CHECK: 'window' or 'full', got 'some'"),
    ("AUTHN_FFT", "fftw", "$AUTHN_FFT: 'numpy' or 'scipy', got 'fftw'"),
    ("AUTHN_SERVE_MAX_DRONES", "-1", "$AUTHN_SERVE_MAX_DRONES: must be positive, got '-1'"),
])
def test_a_malformed_value_is_bad_input_naming_its_variable(name: str, value: str, message: str) -> None:
    with pytest.raises(BadInput) as err:
        settings.load({name: value})
    assert str(err.value) == message


def test_the_service_settings_travel_to_the_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    from authn.service.settings import Settings

    sent = Settings(db_url="sqlite:////tmp/x.sqlite3", max_drones=3, body_timeout_s=2.5, trusted_proxies="10.0.0.0/8",
                    trusted_proxy_header="X-Forwarded-For", figures_dir="/tmp/figs")
    for name, value in sent.to_env().items():
        monkeypatch.setenv(name, value)
    assert Settings.from_env() == sent


def test_docs_list_every_variable_once() -> None:
    """docs/architecture.md's settings table has one row per variable: its name, meaning and
    default as core/settings.py declares them; no page names a product variable that is not there."""
    page = (ROOT / "docs" / "architecture.md").read_text()
    rows = {m.group(1): m.group(0) for m in re.finditer(r"^\| `(AUTHN_[A-Z_]+)` \|.*$", page, re.M)}
    assert sorted(rows) == sorted(v.name for v in settings.VARIABLES)
    for v in settings.VARIABLES:
        assert rows[v.name] == f"| `{v.name}` | {v.doc} | {v.default} |"
        assert page.count(f"`{v.name}`") == 1, v.name
    named = {n for p in [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]
             for n in re.findall(r"AUTHN_[A-Z_]+", p.read_text()) if not n.endswith("_")}  # AUTHN_SERVE_*: a family
    assert named - TEST_ONLY <= set(rows), sorted(named - TEST_ONLY - set(rows))
