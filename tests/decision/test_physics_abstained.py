"""No acceptance on the classifier alone (docs/policies.md).

Where the physics term abstains (no usable blade-flash rate: signatures/classify/verify.py), the classifier
may count against a claim but never carries it: the sequential test counts such a dwell only against
the claim (`authn.sprt.Sprt.increment`), for one dwell as for a track, signed or not. In the
simulated worlds the shipped classifier never favours a claim whose rotors went unseen (it calls
such returns birds), so the dwell where it would is built from real parts: the features of a real
dwell whose rotors are not resolvable (blades 30 dB under the body at 5 dB SNR: no flash scores 1)
and the shipped classifier's own probabilities for a real genuine M300 dwell. Real verification,
real evidence, real Cedar.
"""

from __future__ import annotations

import math
from dataclasses import asdict, replace
from datetime import datetime, timezone

import pytest

from authn.check import Checker
from authn.demo import register_examples
from authn.evidence import Evidence, RadarEvidence, RegistryFacts, RemoteIdAuth, read_claim
from authn.policy import PolicyEngine
from authn.scenario import Broadcast, simulate_flight
from authn.track import DWELL_CAP_NATS, Sprt
from registry.dbapi import IdentityFacts
from signatures.features import extract
from signatures.classify.inference import classifier_for
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.scene import Scene
from signatures.classify.verify import MIN_FLASH_SCORE, verify

M300 = "1581BDEM00000002"
START = datetime.now(timezone.utc).replace(microsecond=0)


def _m300(seed: int, **scene):
    sc = Scene(kind="uav", profile=shipped_profiles()["m300"], range_m=400.0, radial_speed_mps=3.0,
               elevation_deg=10.0, **{"snr_db": 20.0, **scene})
    rec, _ = simulate_flight(sc, get_preset("paper"), seed, Broadcast(serial=M300), azimuth_deg=60.0,
                             start_time=START)
    return rec


def _radar(rec, probabilities_of=None):
    """(features, the classifier's prediction) of `rec`; the prediction of `probabilities_of` if given."""
    feats = extract(rec, expected_range_m=400.0)
    src = extract(probabilities_of, expected_range_m=400.0) if probabilities_of is not None else feats
    clf = classifier_for(rec, None, "test")
    pred = clf.predict_many(src.as_array()[None], lambda: src.rd_patch[None])[0]
    return feats, pred


def _unresolved_rotors():
    """The first of a few seeds whose M300 dwell is detected but shows no usable flash rate."""
    for seed in range(10):
        rec = _m300(seed, snr_db=5.0, blade_to_body_db=-30.0)
        feats = extract(rec, expected_range_m=400.0)
        if feats.detected and feats.features.flash_score < MIN_FLASH_SCORE:
            return rec
    pytest.fail("no seed gave a detected M300 return with unresolved rotors")


@pytest.fixture(scope="module")
def dwells():
    return _unresolved_rotors(), _m300(1)


def _decide(rec, feats, pred, llr: float | None = None, auth: str = "absent",
            sprt: Sprt | None = None) -> tuple[object, object]:
    """(verification, policy result) of one dwell claiming an M300; `llr` replaces the verification's
    (against every alternative); `auth`: the Remote ID's DRIP status; `sprt`: the error targets."""
    profile = shipped_profiles()["m300"]
    v = verify({**asdict(feats.features), **feats.physics}, profile, pred.probabilities,
               rec.config.unambiguous_velocity_mps, known=pred.known)
    if llr is not None:
        v = replace(v, llr=llr, against={k: llr for k in v.against})
    since = datetime(2025, 1, 1, tzinfo=timezone.utc)
    facts = RegistryFacts(IdentityFacts("1581F000", "serial", "m300", "active", since, None))
    radar = RadarEvidence(gated=True, model=pred.label, confidence=pred.confidence, known=pred.known,
                          range_m=float(feats.range_m), radial_velocity_mps=float(feats.radial_velocity_mps),
                          verification=v)
    ev = Evidence(read_claim(rec, None), facts, int(rec.start_time.timestamp()), [], preset="paper", radar=radar,
                  auth=RemoteIdAuth(auth), sprt=sprt)
    return v, PolicyEngine.load().decide(M300, ev.principal(), ev.resource(), ev.context())


#: Error targets loose enough for one dwell to decide (3.89 / -3.89 nats, below the 4-nat cap).
LOOSE = Sprt(0.02, 0.02)


def test_the_classifier_alone_does_not_carry_a_claim(dwells) -> None:
    weak, genuine = dwells
    feats, pred = _radar(weak, probabilities_of=genuine)  # unresolved rotors, a classifier sure of the claim
    v, result = _decide(weak, feats, pred, sprt=LOOSE)
    # the shipped bundle's support for the claim, whatever its temperature makes of it: positive, over 1 nat
    assert v.physics_abstained and set(v.terms) == {"classifier"} and v.terms["classifier"] > 1.0
    assert v.against["unknown"] == v.terms["classifier"]
    # not even at targets one dwell can meet, nor with a valid signature: it counts 0 for the claim
    assert (result.decision, result.reasons) == ("inconclusive", ["radar-inconclusive"])
    assert _decide(weak, feats, pred, auth="valid")[1].decision == "inconclusive"
    # the same classifier with the rotors seen: physics verifies, one dwell decides at the loose targets
    v, result = _decide(genuine, *_radar(genuine), sprt=LOOSE)
    assert not v.physics_abstained and v.terms["physics"] > 0
    assert v.llr >= LOOSE.accept_nats and (result.decision, result.reasons) == ("accept", ["registered-active"])


def test_an_llr_that_is_not_a_number_is_not_accepted(dwells) -> None:
    """Fail closed: a verification LLR of NaN counts as far against the claim as a dwell may (clamping
    it would have made it the most positive), so the genuine dwell that was accepted is not, signed or
    not; at targets one dwell can refute, it is rejected."""
    _, genuine = dwells
    feats, pred = _radar(genuine)
    assert _decide(genuine, feats, pred, sprt=LOOSE)[1].decision == "accept"
    v, result = _decide(genuine, feats, pred, llr=math.nan, sprt=LOOSE)
    assert math.isnan(v.llr) and result.decision == "reject"
    for auth in ("absent", "valid"):
        v, result = _decide(genuine, feats, pred, llr=math.nan, auth=auth)
        assert result.decision == "inconclusive"


def test_a_check_counts_an_abstention_only_against_the_claim(dwells, tmp_path) -> None:
    """The check itself: the unresolved dwell's request carries a test record that cannot favour the
    claim; the genuine one's favours it (one dwell, capped, stays below the default accept bound)."""
    weak, genuine = dwells
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(db)
    checker = Checker(db)
    out = checker.evaluate_recording(weak)
    record = out.evidence.context()["track"]
    assert record["llr_cn"] <= 0 and out.decision != "accept"
    assert "physics" not in out.to_json()["radar"]["verification"]["terms"]
    ok = checker.evaluate_recording(genuine)
    record = ok.evidence.context()["track"]
    assert 0 < record["llr_cn"] <= DWELL_CAP_NATS * 100 < record["accept_cn"] and ok.decision == "inconclusive"
