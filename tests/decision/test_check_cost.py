"""What a check pays for beyond its work: the audit's signing library imported while the radar
runs (and a failure there still failing closed), and a batch asking the registry and the bundle
finder once per question, not once per return. (Timings: benchmarks/check_cost.py.)"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from authn.audit.log import SIGNING_MODULES
from tests.flights import write_m300_flight


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Path]:
    from authn.demo import register_examples

    folder = tmp_path_factory.mktemp("cost")
    url = f"sqlite:///{folder / 'r.sqlite3'}"
    register_examples(url)
    return url, write_m300_flight(folder)


DECIDE = """
import json, sys, threading
from authn.check import CheckInput, Checker
checker = Checker(sys.argv[1])
before = [m for m in sys.argv[3:] if m in sys.modules]
batch = checker.decide([CheckInput.file(sys.argv[2])])
print(json.dumps({"before": before, "after": [m for m in sys.argv[3:] if m in sys.modules],
                  "threads": threading.active_count(), "decision": batch.items[0].decision}))
"""


def test_the_radar_stage_imports_what_signing_the_log_needs(flight: tuple[str, Path]) -> None:
    """A cold check's audit stage no longer pays the cryptography import: the radar stages made
    it, in a thread that has ended by the time they return."""
    url, path = flight
    proc = subprocess.run([sys.executable, "-c", DECIDE, url, str(path), *SIGNING_MODULES],
                          capture_output=True, text=True, timeout=120)
    report = json.loads(proc.stdout)
    assert report["decision"] == "inconclusive", proc.stderr  # the radar ran
    assert report["before"] == []
    assert report["after"] == list(SIGNING_MODULES)
    assert report["threads"] == 1


BROKEN = """
import sys
from importlib.abc import MetaPathFinder

class Broken(MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "cryptography.hazmat.primitives.serialization":
            raise ImportError("damaged install")

sys.meta_path.insert(0, Broken())
from authn.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_signing_library_that_does_not_import_fails_the_check_closed(flight: tuple[str, Path]) -> None:
    url, path = flight
    proc = subprocess.run([sys.executable, "-c", BROKEN, "--db", url, "check", str(path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 3, proc.stderr
    assert proc.stdout == ""  # no decision printed: none was recorded
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr


def test_a_batch_asks_the_registry_and_the_bundle_finder_once(flight: tuple[str, Path],
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """Six returns of one waveform and one registered model: one bundle lookup and one read of
    the site's active models, not six; each decision as the return decided alone (the
    features of a batch come from other FFTs than one return's: `Checker._features`)."""
    import signatures.classify.inference as inference
    from authn.check import CheckInput, Checker
    from registry.dbapi import Database

    url, path = flight
    alone = Checker(url).decide_one(CheckInput.file(path))
    calls: dict[str, int] = {}

    def counted(owner: object, name: str) -> None:
        real = getattr(owner, name)

        def spy(*args, **kwargs):
            calls[name] = calls.get(name, 0) + 1
            return real(*args, **kwargs)
        monkeypatch.setattr(owner, name, spy)

    counted(inference, "classifier_for")
    counted(Database, "registered_profiles")
    counted(Database, "profile")
    batch = Checker(url).decide([CheckInput.file(path) for _ in range(6)])
    assert calls == {"classifier_for": 1, "registered_profiles": 1, "profile": 1}
    assert [(o.decision, o.reasons) for o in batch.items] == [(alone.decision, alone.reasons)] * 6
