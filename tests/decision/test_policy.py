"""Golden decision table for the default Cedar policy (one row per policy, combinations, accept)."""

from __future__ import annotations

from pathlib import Path

import pytest

from authn.policy import PolicyEngine, PolicyError

T_NOW = 1_767_268_800  # 2026-01-01T12:00:00Z

ACTIVE = dict(registered=True, status="active", model="m300", id_type="serial", valid_from_s=T_NOW - 86400,
              has_key=False)
SITE = dict(time_s=T_NOW, preset="paper")
def sprt_record(llr_cn: int, dwells: int = 1) -> dict:
    """The sequential test's record (authn.track.Sprt.record) at the default bounds (6.90 / -4.61 nats)."""
    return {"llr_cn": llr_cn, "accept_cn": 690, "reject_cn": -461, "dwells": dwells}


GOOD = dict(claim_source="remote_id", radar_run=True, target_detected=True, radar_model="m300", radar_known=True,
            radar_confidence_bp=9700, has_kinematics=True, range_residual_cm=120, range_tolerance_cm=850,
            velocity_residual_cmps=40, velocity_tolerance_cmps=170, remote_id_present=True, remote_id_issues=[],
            remote_id_auth="absent", track=sprt_record(700))
#: What the check knows before the radar runs (authn.check._skipped_context).
NO_RADAR = {**GOOD, "radar_run": False, "target_detected": False, "radar_model": "", "radar_known": False,
            "radar_confidence_bp": 0, "has_kinematics": False, "range_residual_cm": 0, "range_tolerance_cm": 0,
            "velocity_residual_cmps": 0, "velocity_tolerance_cmps": 0}
del NO_RADAR["track"]

CASES: dict[str, tuple[dict, dict, dict, str, list[str]]] = {
    "accept": ({}, {}, {}, "accept", ["registered-active"]),
    "unregistered": (dict(registered=False, status="unregistered", model="", id_type=""), {}, {},
                     "reject", ["unregistered"]),
    "revoked": (dict(status="revoked"), {}, {}, "reject", ["revoked"]),
    "not yet valid": (dict(valid_from_s=T_NOW + 10), {}, {}, "reject", ["outside-validity-window"]),
    "expired": (dict(valid_until_s=T_NOW), {}, {}, "reject", ["outside-validity-window"]),
    "valid until later": (dict(valid_until_s=T_NOW + 1), {}, {}, "accept", ["registered-active"]),
    "no target": ({}, {}, dict(target_detected=False, track=None), "reject", ["no-target"]),
    # one rule for one dwell and many: the test's record against its bounds
    "claim refuted": ({}, {}, dict(track=sprt_record(-461)), "reject", ["radar-claim-inconsistent"]),
    # refuted on the LLR against the alternatives together, accepted on the least against each
    "one alternative at the bound, not all together": ({}, {}, dict(track={**sprt_record(-500), "refute_llr_cn": -450}),
                                                       "inconclusive", ["radar-inconclusive"]),
    "refuted together": ({}, {}, dict(track={**sprt_record(-500), "refute_llr_cn": -461}), "reject",
                         ["radar-claim-inconsistent"]),
    "just above the reject bound": ({}, {}, dict(track=sprt_record(-460)), "inconclusive", ["radar-inconclusive"]),
    "favours the claim, below the accept bound": ({}, {}, dict(track=sprt_record(689)), "inconclusive",
                                                  ["radar-inconclusive"]),
    "at the accept bound": ({}, {}, dict(track=sprt_record(690)), "accept", ["registered-active"]),
    "a track of eight at the bound": ({}, {}, dict(track=sprt_record(690, 8)), "accept", ["registered-active"]),
    "nothing verified": ({}, {}, dict(track=sprt_record(0, 0)), "inconclusive", ["radar-inconclusive"]),
    "bird, claim refuted": ({}, {}, dict(radar_model="bird", track=sprt_record(-500)), "reject",
                            ["radar-claim-inconsistent", "radar-not-a-drone"]),
    "bird, undecided": ({}, {}, dict(radar_model="bird", track=sprt_record(-300)), "inconclusive",
                        ["radar-inconclusive"]),
    "bird label, claim verified": ({}, {}, dict(radar_model="bird"), "accept", ["registered-active"]),
    # the classifier's own answer informs the score; alone it neither accepts nor rejects
    "classifier names another type, claim verified": ({}, {}, dict(radar_model="phantom4", radar_confidence_bp=5000),
                                                      "accept", ["registered-active"]),
    "open-set unknown, claim verified": ({}, {}, dict(radar_known=False, radar_model="unknown"), "accept",
                                         ["registered-active"]),
    # a valid signature vouches for the identity: the radar need only favour the claim
    "signed, radar favours": ({}, {}, dict(remote_id_auth="valid", track=sprt_record(1)), "accept",
                              ["registered-active"]),
    "signed, radar at 0": ({}, {}, dict(remote_id_auth="valid", track=sprt_record(0)), "inconclusive",
                           ["radar-inconclusive"]),
    "signed, radar against": ({}, {}, dict(remote_id_auth="valid", track=sprt_record(-1)), "inconclusive",
                              ["radar-inconclusive"]),
    "signed, nothing verified": ({}, {}, dict(remote_id_auth="valid", track=sprt_record(0, 0)), "inconclusive",
                                 ["radar-inconclusive"]),
    "signed, radar refutes": ({}, {}, dict(remote_id_auth="valid", track=sprt_record(-461)), "reject",
                              ["radar-claim-inconsistent"]),
    # radar cannot separate the claim from a registered model: a signature decides, else inconclusive
    "confusable, unsigned": ({}, {}, dict(radar_confusable=True), "inconclusive", ["radar-confusable-unsigned"]),
    "confusable, signed": ({}, {}, dict(radar_confusable=True, remote_id_auth="valid"), "accept",
                           ["registered-active"]),
    "confusable and a range mismatch": ({}, {}, dict(radar_confusable=True, range_residual_cm=851), "reject",
                                        ["radar-confusable-unsigned", "range-mismatch"]),
    # the claim's own target (authn/association.py): none in the window, or none where the claim is
    "no target in view": ({}, {}, dict(target_detected=False, targets_in_view=0, track=None), "reject", ["no-target"]),
    "targets in view, none at the claim": ({}, {}, dict(target_detected=False, targets_in_view=2, track=None),
                                           "reject", ["no-radar-target"]),
    "claim's target found among others": ({}, {}, dict(targets_in_view=3), "accept", ["registered-active"]),
    "range mismatch": ({}, {}, dict(range_residual_cm=851), "reject", ["range-mismatch"]),
    "range at tolerance": ({}, {}, dict(range_residual_cm=850), "accept", ["registered-active"]),
    "velocity mismatch": ({}, {}, dict(velocity_residual_cmps=171), "reject", ["velocity-mismatch"]),
    "range mismatch while undecided": ({}, {}, dict(range_residual_cm=851, track=sprt_record(100)), "reject",
                                       ["radar-inconclusive", "range-mismatch"]),
    "remote id implausible": ({}, {}, dict(remote_id_issues=["stale-timestamp"]), "reject",
                              ["remote-id-implausible"]),
    "issues ignored without remote id": ({}, {}, dict(remote_id_present=False, remote_id_issues=["x"]), "accept",
                                         ["registered-active"]),
    "radar skipped, registry ok": ({}, {}, dict(radar_run=False, target_detected=False, track=None), "accept",
                                   ["registered-active"]),
    "spoofed type and position": ({}, {}, dict(track=sprt_record(-500), range_residual_cm=30000), "reject",
                                  ["radar-claim-inconsistent", "range-mismatch"]),
    "revoked and expired": (dict(status="revoked", valid_until_s=T_NOW - 5), {}, {}, "reject",
                            ["outside-validity-window", "revoked"]),
    "signature invalid": ({}, {}, dict(remote_id_auth="invalid"), "reject", ["remote-id-auth-invalid"]),
    "signature expired": ({}, {}, dict(remote_id_auth="expired"), "reject", ["remote-id-auth-expired"]),
    "signed, no key registered": ({}, {}, dict(remote_id_auth="valid"), "accept", ["registered-active"]),
    "unknown key, no key registered": ({}, {}, dict(remote_id_auth="unknown-key"), "accept",
                                       ["registered-active"]),
    "key registered, signed": (dict(has_key=True), {}, dict(remote_id_auth="valid"), "accept",
                               ["registered-active"]),
    "key registered, unsigned": (dict(has_key=True), {}, {}, "reject", ["remote-id-auth-required"]),
    "key registered, unknown key": (dict(has_key=True), {}, dict(remote_id_auth="unknown-key"), "reject",
                                    ["remote-id-auth-required"]),
    "key registered, forged": (dict(has_key=True), {}, dict(remote_id_auth="invalid"), "reject",
                               ["remote-id-auth-invalid", "remote-id-auth-required"]),
}


@pytest.fixture(scope="module")
def engine() -> PolicyEngine:
    return PolicyEngine.load()


@pytest.mark.parametrize("name", list(CASES))
def test_golden_decision(engine: PolicyEngine, name: str) -> None:
    p, r, c, decision, reasons = CASES[name]
    context = {k: v for k, v in {**GOOD, **c}.items() if v is not None}  # None: the attribute is absent
    result = engine.decide("1581BDEM00000002", {**ACTIVE, **p}, {**SITE, **r}, context)
    assert (result.decision, result.reasons) == (decision, reasons)
    assert result.errors == []


@pytest.mark.parametrize("principal,reasons", [
    (dict(registered=False, status="unregistered", model="", id_type=""), ["unregistered"]),
    (dict(status="revoked"), ["revoked"]),
    (dict(valid_until_s=T_NOW - 1), ["outside-validity-window"]),
])
def test_registry_facts_decide_without_evidence(engine: PolicyEngine, principal: dict, reasons: list[str]) -> None:
    result = engine.decide_without_evidence("S1", {**ACTIVE, **principal}, SITE, NO_RADAR)
    assert result is not None and result.decision == "reject" and result.reasons == reasons
    # final whatever the radar says: the same registry facts with the best evidence still reject
    assert engine.decide("S1", {**ACTIVE, **principal}, SITE, GOOD).decision == "reject"


def test_active_identity_needs_the_evidence(engine: PolicyEngine) -> None:
    assert engine.decide_without_evidence("S1", ACTIVE, SITE, NO_RADAR) is None


def test_only_forbids_that_read_no_radar_context_are_final_early(tmp_path: Path) -> None:
    text = ('@id("ctx")\nforbid (principal, action, resource) when { context.radar_run };\n'
            '@id("whole")\nforbid (principal, action, resource) '
            'when { context == context && principal.model == "x" };\n'
            '@id("reg")\nforbid (principal, action, resource) when { principal.status == "revoked" };\n'
            '@id("auth")\nforbid (principal, action, resource) when { context.remote_id_auth == "invalid" };\n'
            '@id("ok")\npermit (principal, action, resource);\n')
    f = tmp_path / "p.cedar"
    f.write_text(text)
    custom = PolicyEngine.load(f)
    assert len(custom.context_free_forbids) == 2  # "reg" and "auth"
    forged = {**NO_RADAR, "remote_id_auth": "invalid"}
    assert custom.decide_without_evidence("S1", ACTIVE, SITE, forged).reasons == ["auth"]
    revoked = {**ACTIVE, "status": "revoked"}
    assert custom.decide_without_evidence("S1", revoked, SITE, NO_RADAR).reasons == ["reg"]
    # a satisfied forbid that reads context is not final: the radar must run
    assert custom.decide_without_evidence("S1", ACTIVE, SITE, {**NO_RADAR, "radar_run": True}) is None


def test_policy_file_replaces_default(tmp_path: Path) -> None:
    strict = tmp_path / "strict.cedar"
    strict.write_text('@id("only-m600")\npermit (principal, action == Action::"authenticate", resource)\n'
                      'when { principal.registered && principal.model == "m600" };\n')
    engine = PolicyEngine.load(strict)
    assert engine.source == str(strict) and engine.sha256 != PolicyEngine.load().sha256
    assert engine.decide("S1", ACTIVE, SITE, GOOD).decision == "reject"
    assert engine.decide("S1", {**ACTIVE, "model": "m600"}, SITE, GOOD).reasons == ["only-m600"]


@pytest.mark.parametrize("text,fragment", [
    ('permit (principal, action, resource) when { context.no_such_field };', "no_such_field"),
    ('permit (principal, action == Action::"fly", resource);', "fly"),
    ("this is not cedar", ""),
])
def test_invalid_policy_refused_with_cedar_message(tmp_path: Path, text: str, fragment: str) -> None:
    bad = tmp_path / "bad.cedar"
    bad.write_text(text)
    with pytest.raises(PolicyError) as info:
        PolicyEngine.load(bad)
    msg = str(info.value)
    assert "\n" not in msg and str(bad) in msg and fragment in msg


def test_a_site_may_accept_one_dwell_at_its_own_targets(tmp_path: Path) -> None:
    """docs/policies.md: the bounds are the site's false-accept and false-reject targets; at 2 % each
    (3.89 / -3.89 nats) one dwell's capped LLR (4 nats) can decide where the defaults leave it
    inconclusive. An `@outcome` a forbid cannot have is refused."""
    engine = PolicyEngine.load()
    loose = {"llr_cn": 400, "accept_cn": 389, "reject_cn": -389, "dwells": 1}
    assert engine.decide("S1", ACTIVE, SITE, {**GOOD, "track": sprt_record(400)}).decision == "inconclusive"
    assert engine.decide("S1", ACTIVE, SITE, {**GOOD, "track": loose}).decision == "accept"
    assert engine.decide("S1", ACTIVE, SITE, {**GOOD, "track": {**loose, "llr_cn": -400}}).reasons == [
        "radar-claim-inconsistent"]
    bad = tmp_path / "bad.cedar"
    bad.write_text('@id("x")\n@outcome("inconclusive")\npermit (principal, action, resource);\n')
    with pytest.raises(PolicyError, match="outcome"):
        PolicyEngine.load(bad)
