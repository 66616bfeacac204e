"""The site's score calibration (`signatures.classify.calibration`): fitted on cross-validated verification
terms, stored in the card, applied by `signatures.classify.verify` only where a site bundle applies it.

Synthetic terms only: the enrolment end to end (the card's `calibration`, `--calibrate`, a check
with it) is in test_enrol.py.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from authn.track import Sprt
from signatures.classify.calibration import Calibration, RawTerms, calibration_of, fit
from signatures.train.separability import CALIBRATION_GAIN, CONFUSABLE_ERROR, calibration_pays, separation
from signatures.errors import SignaturesError
from signatures.profiles import shipped_profiles
from signatures.classify.verify import CLASSIFIER_CLIP, verify

M300 = shipped_profiles()["m300"]
#: a clean M300 return: its own flash rate, a confident flash score, four rotors of its four
FEATS = {"flash_rate_hz": M300.blade_flash_rate_hz, "flash_rate_std_hz": 0.02 * M300.blade_flash_rate_hz,
         "flash_score": 5.0, "rotors_seen": 4.0, "rotors_seen_std": 1.0}
PROBS = {"m300": 0.9, "m600": 0.05, "phantom4": 0.05, "bird": 0.0, "none": 0.0}


def _synthetic(n: int, rng: np.random.Generator, genuine_share: float = 0.5) -> tuple[list[RawTerms], list[bool]]:
    """Genuine claims: physics ~ N(2, 0.5), classifier odds ~ N(1.5, 1); type spoofs: N(-3, 2), N(-1.5, 1)."""
    y = rng.random(n) < genuine_share
    phys = np.where(y, rng.normal(2.0, 0.5, n), rng.normal(-3.0, 2.0, n))
    odds = np.where(y, rng.normal(1.5, 1.0, n), rng.normal(-1.5, 1.0, n))
    return [RawTerms(float(p), float(o)) for p, o in zip(phys, odds)], list(map(bool, y))


def test_fit_orders_genuine_above_type_spoofs_and_carries_no_prior() -> None:
    rng = np.random.default_rng(3)
    raws, y = _synthetic(600, rng)
    cal = fit(raws, y)
    assert all(c >= 0.0 for c in cal.coef) and cal.coef[0] + cal.coef[1] > 0 and cal.coef[2] > 0
    test, ty = _synthetic(400, rng)
    s = np.array([cal.llr(r) for r in test])
    g, i = s[np.array(ty)], s[~np.array(ty)]
    assert np.median(g) > 1.0 > -1.0 > np.median(i)
    auc = np.mean(g[:, None] > i[None, :])
    assert auc > 0.97
    # the classes are weighted equally: three times more type spoofs does not shift the scores by their prior
    raws3, y3 = _synthetic(1200, np.random.default_rng(4), genuine_share=0.25)
    cal3 = fit(raws3, y3)
    s3 = np.array([cal3.llr(r) for r in test])
    assert abs(float(np.median(s3 - s))) < 0.5 < math.log(3.0)
    assert cal.fitted_on == {"genuine": sum(y), "type_spoof": len(y) - sum(y)}


def test_fit_gives_an_uninformative_term_no_weight_and_never_a_negative_slope() -> None:
    rng = np.random.default_rng(5)
    raws, y = _synthetic(600, rng)
    noise = [RawTerms(float(rng.normal(0, 2)), r.classifier_odds) for r in raws]  # physics says nothing
    cal = fit(noise, y)
    assert cal.coef[0] + cal.coef[1] < 0.1 and cal.coef[2] > 0.5
    flipped = [RawTerms(-r.physics, r.classifier_odds) for r in raws]  # physics says the opposite: floored at 0
    assert min(fit(flipped, y).coef) >= 0.0
    with pytest.raises(SignaturesError):
        fit(raws[:3], [True] * 3)


def test_abstained_physics_never_yields_a_positive_increment() -> None:
    cal = Calibration(coef=(0.5, 0.5, 2.0), intercept=3.0)  # a calibration that would favour any claim
    abstained = {**FEATS, "flash_score": 0.0}  # no usable rate estimate: the physics term abstains
    v = verify(abstained, M300, PROBS, known=True, calibration=cal)
    assert v.physics_abstained and "physics" not in v.terms and v.llr > 0
    sprt = Sprt()
    assert sprt.increment(v.llr, not v.physics_abstained) == 0.0
    assert sprt.walk([(v.llr, not v.physics_abstained)] * 8)[0] != "accept"
    # nothing scored at all (no physics, no classifier class): no terms, nothing for the track to add
    none = verify(abstained, M300, None, calibration=cal)
    assert none.terms == {} and none.llr == 0.0
    # with physics present the same calibration may count for the claim
    ok = verify(FEATS, M300, PROBS, calibration=cal)
    assert not ok.physics_abstained and sprt.increment(ok.llr, True) > 0


def test_unknown_return_keeps_the_classifier_from_counting_for_the_claim() -> None:
    cal = Calibration(coef=(0.0, 0.0, 1.0), intercept=0.0)
    v = verify(FEATS, M300, PROBS, known=False, calibration=cal)
    assert v.terms["classifier"] == 0.0


def test_without_calibration_verify_is_unchanged() -> None:
    """The shipped path: no calibration gives the clipped sum of the physics and classifier terms."""
    plain = verify(FEATS, M300, PROBS)
    same = verify(FEATS, M300, PROBS, calibration=None)
    assert plain == same and plain.uncalibrated == {} and "uncalibrated" not in plain.to_json()
    assert set(plain.terms) == {"physics", "classifier"} and plain.llr == sum(plain.terms.values())
    prior = 1.0 / 3.0
    odds = math.log(0.9 / 0.1) - math.log(prior / (1.0 - prior))
    assert plain.terms["classifier"] == min(CLASSIFIER_CLIP, odds)
    assert plain.raw.classifier_odds == pytest.approx(odds) and plain.raw.physics == plain.terms["physics"]
    cal = verify(FEATS, M300, PROBS, calibration=Calibration(coef=(1.0, 0.0, 1.0), intercept=0.0))
    assert cal.uncalibrated == plain.terms  # the calibrated check still reports what verify said


def test_shipped_bundle_applies_no_calibration() -> None:
    from signatures.classify.inference import load_classifier

    assert calibration_of(load_classifier(preset="paper")) is None


class _Bundle:
    def __init__(self, card: dict) -> None:
        self.card = card


def test_coefficients_round_trip_through_the_card() -> None:
    raws, y = _synthetic(300, np.random.default_rng(8))
    cal = fit(raws, y)
    doc = json.loads(json.dumps({"enrolment": {"calibration": cal.to_json()}}))  # as card.json stores it
    back = calibration_of(_Bundle(doc))
    assert back is not None and back.applied
    assert back.coef == pytest.approx(cal.coef, abs=1e-8) and back.intercept == pytest.approx(cal.intercept, abs=1e-8)
    for r in raws[:20]:
        assert back.llr(r) == pytest.approx(cal.llr(r), abs=1e-6)
    # fitted but not applied (the default enrolment): the check verifies as without it
    off = json.loads(json.dumps({"enrolment": {"calibration": fit(raws, y, applied=False).to_json()}}))
    assert calibration_of(_Bundle(off)) is None
    assert calibration_of(_Bundle({"enrolment": {"bands": None}})) is None
    # a card that says something this version would misread is refused, not guessed at
    for bad in ({"coef": [-1.0, 0.0, 1.0]}, {"features": ["physics", "classifier"]}, {"format": "other/1"},
                {"intercept": "nan"}, {"physics_knee": 0.0}):
        with pytest.raises(SignaturesError):
            calibration_of(_Bundle({"enrolment": {"calibration": {**cal.to_json(), **bad}}}))


def _choice(gen_u, fa_u, gen_c, fa_c) -> dict:
    return {"uncalibrated": {"level": "tracks", "genuine_accept": gen_u, "worst_pair_false_accept": fa_u},
            "calibrated": {"level": "tracks", "genuine_accept": gen_c, "worst_pair_false_accept": fa_c}}


def test_calibration_is_applied_unasked_only_where_the_site_scores_say_it_pays() -> None:
    assert calibration_pays(_choice(0.52, 0.0, 0.52 + CALIBRATION_GAIN, 0.0))  # a clear gain, no new false accepts
    assert not calibration_pays(_choice(0.52, 0.0, 0.52 + CALIBRATION_GAIN / 2, 0.0))  # within the folds' noise
    assert not calibration_pays(_choice(0.52, 0.0, 0.04, 0.0))  # the held-out world's case: it loses
    assert not calibration_pays(_choice(0.5, 0.0, 0.9, 2 * CONFUSABLE_ERROR))  # it buys genuine with false accepts
    assert calibration_pays(_choice(0.5, 0.03, 0.9, 0.03))  # false accepts no worse than without it
    assert not calibration_pays(_choice(None, None, 0.9, 0.0))  # nothing to compare


def test_separation_reads_the_walk_of_each_pair() -> None:
    """Genuine tracks of strong positive dwells are accepted, type-spoof tracks of negative ones are not."""
    sprt = Sprt()
    dwells = {("a", "a"): [(4.0, True)] * 10, ("b", "b"): [(4.0, True)] * 10,
              ("a", "b"): [(-4.0, True)] * 10, ("b", "a"): [(1.0, True), (-4.0, True)] * 5}
    sep = separation([], {}, dwells, ["a", "b"], sprt, seed=0)
    assert sep == {"level": "tracks", "genuine_accept": 1.0, "worst_pair_false_accept": 0.0}
    single = separation([1.0, -1.0, 2.0, 3.0], {("a", "b"): [-1.0, 0.5], ("b", "a"): [-2.0, -3.0]}, dwells,
                         ["a", "b"], None, seed=0)
    assert single == {"level": "single_dwell", "genuine_accept": 0.75, "worst_pair_false_accept": 0.5}


def test_an_unknown_calibrate_value_is_bad_input(capsys) -> None:
    from authn.cli import main

    assert main(["models", "enrol", "nowhere", "--calibrate", "maybe"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--calibrate 'maybe': one of auto, on, off" in err


def test_a_calibration_never_supports_a_claim_by_itself() -> None:
    """A site whose genuine dwells carry little evidence (physics ~ +0.2, the classifier calls them
    unknown) against impostors the physics refutes: an unconstrained fit puts the support in its
    intercept, which any return the classifier calls unknown would then get. The fit keeps the
    intercept <= 0, and a card fitted before (intercept +4.4) is clipped where it is applied."""
    rng = np.random.default_rng(11)
    n = 400
    y = rng.random(n) < 0.5
    phys = np.where(y, rng.normal(0.2, 0.15, n), rng.normal(-3.0, 1.5, n))
    raws = [RawTerms(float(p), 2.5, known=False) for p in phys]  # the classifier's odds capped at 0: unknown
    cal = fit(raws, list(map(bool, y)))
    assert cal.intercept <= 0.0
    impostors_unknown = [RawTerms(0.0, float(o), known=False) for o in (-1.0, 0.0, 2.0, 8.0)] + [RawTerms(0.0, None)]
    assert all(cal.llr(r) <= 0.0 for r in impostors_unknown)
    old = Calibration(coef=cal.coef, intercept=4.4)  # the held-out site's: +4.4 nats from nothing
    assert all(old.llr(r) <= 0.0 for r in impostors_unknown)
    v = verify({**FEATS, "flash_rate_hz": 0.6 * FEATS["flash_rate_hz"]}, M300, PROBS, known=False, calibration=old)
    assert v.terms["offset"] == 0.0 and v.llr <= v.terms["physics"]
