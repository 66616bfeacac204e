"""The path of one check goes one way: Cedar's request is the one it evaluated (captured when
sent, kept for replay), the evidence and the Outcome are frozen values, the evidence's context
and JSON view are each built once per check, and a batch asks Cedar once per stage with every
return's reasons as when it is decided alone."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cedarpy
import pytest

from tests.flights import write_m300_flight

from authn.check import CheckInput, Checker, Outcome
from authn.demo import UNREGISTERED, register_examples
from authn.evidence import Evidence
from authn.policy import PolicyEngine

M600, M300, REVOKED = "1581BDEM00000001", "1581BDEM00000002", "1581BDEM00000003"
#: claimed serials over one recorded M300 flight: the radar runs (M600, M300), the registry decides
CLAIMS = (M300, UNREGISTERED, M600, REVOKED, M300, UNREGISTERED)
#: a forbid whose condition errors on the radar's claims (an integer overflow): fail closed
ERRORING = """
@id("overflowing-check")
forbid (principal, action == Action::"authenticate", resource)
when { context.radar_run && principal.valid_from_s + 9223372036854775807 > 0 };
"""
#: a policy that names the site entity: its requests are never batched under other ids
NAMES_SITE = """
@id("this-site-only")
forbid (principal, action == Action::"authenticate", resource)
unless { resource == RadarSite::"site" };
"""


@pytest.fixture(scope="module")
def flight(tmp_path_factory) -> Path:
    return write_m300_flight(tmp_path_factory.mktemp("path"))


@pytest.fixture
def db(tmp_path: Path) -> str:
    url = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(url)
    return url


def _shipped(extra: str = "") -> PolicyEngine:
    from importlib import resources

    return PolicyEngine.from_text(resources.files("authn.policies").joinpath("default.cedar").read_text() + extra)


def _counting(monkeypatch, owner: object, name: str) -> list[int]:
    calls: list[int] = []
    real = getattr(owner, name)

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, name, counted)
    return calls


def test_decide_returns_the_request_it_sent() -> None:
    from authn.policy import policy_input

    principal = {"registered": True, "status": "active", "model": "m300", "id_type": "serial", "valid_from_s": 0,
                 "has_key": False}
    resource, context = {"time_s": 1, "preset": "paper"}, {"claim_source": "cli", "radar_run": False}
    result = PolicyEngine.load().decide("S1", principal, resource, context)
    assert result.request == policy_input("S1", principal, resource, context)
    assert result.request["context"] is context  # the value sent, not a copy rebuilt afterwards


def test_outcome_and_evidence_are_frozen(flight: Path, db: str) -> None:
    out = Checker(db).evaluate(flight, M300)
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.audit_id = 7  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.evidence.radar = None  # type: ignore[misc]


@pytest.mark.parametrize("serial, contexts", [(UNREGISTERED, 1), (M300, 2)])
def test_context_and_report_built_once_per_check(flight: Path, db: str, monkeypatch, serial: str,
                                                 contexts: int) -> None:
    """A registry-decided check builds one context (its one request), a radar check two (before
    and after the radar); the evidence's JSON is rendered once for the audit payload and the print."""
    checker = Checker(db)
    context = _counting(monkeypatch, Evidence, "context")
    report = _counting(monkeypatch, Evidence, "report")
    out = checker.check([CheckInput.file(flight, serial)]).items[0]
    assert isinstance(out, Outcome) and out.audit_id is not None
    out.to_json()
    assert (len(context), len(report)) == (contexts, 1)
    assert out.audit_payload()["policy_input"] is out.request  # the request that decided it


def test_a_batch_asks_cedar_once_per_stage_with_each_alone_reasons(flight: Path, db: str, monkeypatch) -> None:
    checker = Checker(db)
    alone = [checker.evaluate(flight, s) for s in CLAIMS]
    calls = _counting(monkeypatch, cedarpy, "is_authorized_batch")
    batch = checker.decide([CheckInput.file(flight, s) for s in CLAIMS])
    assert len(calls) == 2  # before the radar, then the radar's decisions: not one or two per return
    assert [(o.decision, o.reasons, o.policy_errors, o.request) for o in batch.items] == \
        [(o.decision, o.reasons, o.policy_errors, o.request) for o in alone]
    assert [o.audit_payload() for o in batch.items] == [o.audit_payload() for o in alone]


def test_an_erroring_policy_rejects_in_a_batch_as_alone(flight: Path, db: str, tmp_path: Path,
                                                         monkeypatch) -> None:
    """Cedar's evaluation error text is a single check's, the batch's site ids never in it."""
    policy = tmp_path / "site.cedar"
    policy.write_text(_shipped(ERRORING).text)
    checker = Checker(db, policy)
    alone = [checker.evaluate(flight, s) for s in CLAIMS]
    calls = _counting(monkeypatch, cedarpy, "is_authorized_batch")
    batch = checker.decide([CheckInput.file(flight, s) for s in CLAIMS])
    erred = sum("policy-error" in o.reasons for o in alone)
    assert erred and len(calls) == 2 + erred  # each erring request asked again alone
    assert [(o.decision, o.reasons, o.policy_errors) for o in batch.items] == \
        [(o.decision, o.reasons, o.policy_errors) for o in alone]
    assert not any("#" in e for o in batch.items for e in o.policy_errors)


def test_a_policy_naming_the_site_is_asked_one_request_at_a_time(flight: Path, db: str, tmp_path: Path,
                                                                  monkeypatch) -> None:
    policy = tmp_path / "site.cedar"
    policy.write_text(_shipped(NAMES_SITE).text)
    checker = Checker(db, policy)
    assert not checker.policy.batchable and _shipped().batchable
    alone = [checker.evaluate(flight, s) for s in CLAIMS]
    calls = _counting(monkeypatch, cedarpy, "is_authorized")
    batch = checker.decide([CheckInput.file(flight, s) for s in CLAIMS])
    assert len(calls) == len(CLAIMS) + sum(o.radar is not None for o in alone)
    assert [(o.decision, o.reasons) for o in batch.items] == [(o.decision, o.reasons) for o in alone]


def _engine_fails_after_the_radar(monkeypatch) -> None:
    """Cedar raises on any request made after the radar ran (the policy engine fails mid-batch)."""
    real = cedarpy.is_authorized_batch

    def failing(requests, *args, **kwargs):
        if any(r["context"]["radar_run"] for r in requests):
            raise RuntimeError("engine exploded")
        return real(requests, *args, **kwargs)

    monkeypatch.setattr(cedarpy, "is_authorized_batch", failing)


def test_an_engine_fault_after_the_radar_fails_each_return_it_left(flight: Path, db: str, monkeypatch) -> None:
    """Every return read is accounted for: decided before the fault, or a Failure (exit 3) to audit."""
    checker = Checker(db)
    _engine_fails_after_the_radar(monkeypatch)
    batch = checker.decide([CheckInput.file(flight, s) for s in (M300, UNREGISTERED, M600)])
    assert batch.fault is not None
    assert [o.decision if isinstance(o, Outcome) else o.exit_code for o in batch.items] == [3, "reject", 3]


def test_an_engine_fault_after_the_radar_exits_3_with_one_line(flight: Path, db: str, monkeypatch, capsys) -> None:
    import sqlite3

    from authn.cli import main

    _engine_fails_after_the_radar(monkeypatch)
    capsys.readouterr()
    assert main(["--db", db, "check", str(flight), "--serial", M300, "--json"]) == 3
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("error: ") and "policy engine" in err and err.count("\n") == 1
    rows = sqlite3.connect(db.removeprefix("sqlite:///")).execute("select kind from audit_log").fetchall()
    assert rows == [("error",)]
