"""The default policy and a CW recording's missing range: an unchecked position is not a
passed one (`range-not-measured`), and requests recorded before `range_measured` existed
still validate and decide as before."""

from __future__ import annotations

import pytest

from authn.policy import PolicyEngine
from tests.decision.test_policy import ACTIVE, GOOD, SITE


@pytest.mark.parametrize("extra,decision,reasons", [
    (dict(range_measured=False, range_residual_cm=0, range_tolerance_cm=0), "reject", ["range-not-measured"]),
    (dict(range_measured=False, has_kinematics=False), "accept", ["registered-active"]),
    (dict(range_measured=False, target_detected=False), "reject", ["no-target"]),
    (dict(range_measured=True), "accept", ["registered-active"]),
    ({}, "accept", ["registered-active"]),  # an audit entry from before range_measured
    (dict(range_measured=False, track={"llr_cn": -500, "accept_cn": 690, "reject_cn": -461, "dwells": 2}), "reject",
     ["radar-claim-inconsistent", "range-not-measured"]),
])
def test_missing_range_is_not_a_pass(extra: dict, decision: str, reasons: list[str]) -> None:
    result = PolicyEngine.load().decide("S1", ACTIVE, SITE, {**GOOD, **extra})
    assert (result.decision, result.reasons, result.errors) == (decision, reasons, [])


def test_a_cw_file_still_runs_the_radar() -> None:
    """range_measured is known before the radar, but the forbid also reads radar facts: it
    never ends a check early."""
    from tests.decision.test_policy import NO_RADAR

    assert PolicyEngine.load().decide_without_evidence("S1", ACTIVE, SITE, {**NO_RADAR, "range_measured": False}) \
        is None
