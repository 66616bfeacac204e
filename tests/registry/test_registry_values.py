"""One internal value type in the registry (docs/architecture.md): its records are
`core.checked` dataclasses, pydantic stays at the HTTP edge (authn.service), so the registry
store, its import and export run without pydantic."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from core.checked import Checked
from registry.errors import RegistryError
from registry.store import IdentityRecord, NewIdentity, parse_import
from tests.test_architecture import ROOT


def test_registry_records_are_checked_dataclasses() -> None:
    assert issubclass(NewIdentity, Checked) and issubclass(IdentityRecord, Checked)


def test_the_registry_store_imports_no_pydantic() -> None:
    script = ("import sys, registry.store; "
              "print(sorted(m for m in sys.modules if m.split('.')[0] in ('pydantic', 'pydantic_core')))")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize("value, match", [
    (1700000000, r"^exported_at: 1700000000 is not an ISO 8601 date/time string$"),
    ("yesterday", r"^exported_at: 'yesterday' is not an ISO 8601 date/time"),
])
def test_exported_at_is_read_as_the_records_times_are(value, match) -> None:
    """The document's time as its records' (ISO 8601 text, never epoch seconds)."""
    import json

    with pytest.raises(RegistryError, match=match):
        parse_import(json.dumps({"format": "authn-registry/1", "exported_at": value}))
