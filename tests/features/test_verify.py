"""1:1 verification (`signatures.classify.verify`): physics against the claimed profile, rate-invariant
where it should be, the classifier's say bounded, a new profile verifiable without retraining."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.profiles import UavProfile, shipped_profiles
from signatures.classify.verify import CLASSIFIER_CLIP, MIN_FLASH_GROUPS, RATE_BAND, TERM_FLOOR, verify

P = shipped_profiles()
WIDE_MAX_TIP = 156.0  # the wide preset's unambiguous velocity: tips never alias there


def _seen(flown: UavProfile, rate_scale: float = 1.0, cos_el: float = 1.0, aliased: bool = False,
          flash_scale: float = 1.0) -> dict[str, float]:
    """The estimates a clean return of `flown` gives (flash rate, LOS tip speed, their stds)."""
    f = flown.blade_flash_rate_hz * rate_scale * flash_scale
    return {"flash_rate_hz": f, "flash_rate_std_hz": 0.01 * f, "flash_score": 5.0,
            "tip_speed_mps": flown.tip_speed_mps * rate_scale * cos_el, "tip_speed_std_mps": 1.0,
            "tip_aliased": float(aliased)}


@pytest.mark.parametrize("slug", list(P))
@pytest.mark.parametrize("scale", [0.85, 1.0, 1.15])
def test_a_genuine_airframe_at_any_flown_rotor_rate_verifies(slug: str, scale: float) -> None:
    v = verify(_seen(P[slug], scale, cos_el=0.95), P[slug], max_tip_mps=WIDE_MAX_TIP)
    assert set(v.terms) == {"physics"} and v.llr > 1.0


def test_rates_outside_the_band_contradict_the_claim() -> None:
    """A Phantom 4 (flash 117 Hz) claiming an M300 (80 Hz) is 1.46x off: beyond RATE_BAND and no slip."""
    v = verify(_seen(P["phantom4"], aliased=True), P["m300"])
    assert v.terms["physics"] < -4.0
    assert 117 / 80 > RATE_BAND[1] * 1.2


def test_blade_ratio_separates_airframes_whose_rates_overlap() -> None:
    """An M600 flown 9 % fast has the M300's flash rate; its tip speed over flash rate (2 pi L / N,
    rotor-rate free) is 25 % too high for an M300 and gives it away when the tips do not alias."""
    seen = _seen(P["m600"], rate_scale=P["m300"].blade_flash_rate_hz / P["m600"].blade_flash_rate_hz)
    assert verify(seen, P["m300"], max_tip_mps=WIDE_MAX_TIP).llr < 0
    assert verify(seen, P["m600"], max_tip_mps=WIDE_MAX_TIP).llr > 0
    # the same return where the claimed tips alias (paper): only the rate speaks, and it fits
    aliased = {**seen, "tip_aliased": 1.0}
    assert verify(aliased, P["m300"], max_tip_mps=22.0).llr > 0


def _rotors(seen: float, groups: int) -> dict[str, float]:
    """`FeatureResult.physics` of `groups` distinct flashes counting `seen` rotors."""
    return {"rotors_seen": seen, "rotors_seen_std": seen / math.sqrt(groups)}


def test_rotors_seen_weigh_against_airframes_whose_rates_and_tips_agree() -> None:
    """An M300 flown 9 % slow has an M600's flash rate, and its shorter blades pass the blade
    test's upper bound: only the rotors it shows (about 4, not 6) count against the M600 claim,
    rate-invariantly. Four of six rotors is at the edge of what collisions and missed flashes
    explain, so it weakens the claim; eight rotors against a quad's four contradict it."""
    seen = _seen(P["m300"], rate_scale=P["m600"].blade_flash_rate_hz / P["m300"].blade_flash_rate_hz)
    without = verify(seen, P["m600"], max_tip_mps=WIDE_MAX_TIP).llr
    assert without > 0  # the physics without the rotors cannot tell
    fewer = {**seen, **_rotors(3.0, 12)}
    assert verify(fewer, P["m600"], max_tip_mps=WIDE_MAX_TIP).llr < without - 0.5
    with_rotors = {**seen, **_rotors(3.6, 15)}
    assert verify(with_rotors, P["m300"], max_tip_mps=WIDE_MAX_TIP).llr > verify(
        with_rotors, P["m600"], max_tip_mps=WIDE_MAX_TIP).llr
    genuine = _seen(P["m600"])
    assert verify({**genuine, **_rotors(5.5, 21)}, P["m600"], max_tip_mps=WIDE_MAX_TIP).llr > without
    # an octocopter's eight rotors against a quad's claim, at a rate the quad could fly
    octo = {**_seen(P["m300"], rate_scale=1.1), **_rotors(7.2, 28)}
    assert verify(octo, P["m300"], max_tip_mps=WIDE_MAX_TIP).llr < 0


def _visible(count: float) -> dict[str, float]:
    """A long dwell's count of the rotors visible above the noise (`signatures.dsp.rotor_lines`)."""
    return {"rotors_seen": count, "rotors_seen_std": 1.0, "rotors_lower_bound": 1.0}


@pytest.mark.parametrize("slug", list(P))
def test_fewer_rotors_visible_than_claimed_is_no_evidence_either_way(slug: str) -> None:
    """A visible-rotor count is a lower bound: untagged or idling rotors under the noise are not
    seen, so 2 of a claim's rotors neither help nor hurt it (the count's one-line blur costs a count
    of all its rotors under a tenth of a nat), and no count makes the claim stronger."""
    seen = _seen(P[slug])
    base = verify(seen, P[slug]).llr
    for count in range(2, P[slug].rotors + 1):
        assert verify({**seen, **_visible(float(count))}, P[slug]).llr == pytest.approx(base, abs=0.1)
    assert all(verify({**seen, **_visible(float(c))}, P[slug]).llr <= base + 1e-9 for c in range(2, 13))


def test_more_rotors_visible_than_claimed_counts_against_the_claim() -> None:
    """An octocopter flying a quad's rate shows 8 lines: a quad claim cannot make them (its 4 and a
    residue line or two), so the claim falls well below where it stood; 5 lines cost a little."""
    seen = _seen(P["m300"], rate_scale=1.05)
    base = verify(seen, P["m300"]).llr
    assert verify({**seen, **_visible(5.0)}, P["m300"]).llr > base - 0.5
    assert verify({**seen, **_visible(8.0)}, P["m300"]).llr < base - 3.0
    assert verify({**seen, **_visible(8.0)}, P["m300"]).llr < 0
    # under a half-rate read each rotor's two blades are two lines: 8 lines, 4 rotors, no veto
    half = _seen(P["m300"], flash_scale=0.5)
    assert verify({**half, **_visible(8.0)}, P["m300"]).llr > verify({**seen, **_visible(8.0)}, P["m300"]).llr


def test_rotors_from_too_few_flashes_abstain() -> None:
    seen = _seen(P["m300"], aliased=True)
    base = verify(seen, P["m300"]).llr
    assert verify({**seen, **_rotors(9.0, MIN_FLASH_GROUPS - 1)}, P["m300"]).llr == base
    assert verify({**seen, "rotors_seen": 4.0, "rotors_seen_std": 0.0}, P["m300"]).llr == base


def test_a_whole_period_slip_weakens_but_does_not_veto() -> None:
    full = verify(_seen(P["m300"], aliased=True), P["m300"]).terms["physics"]
    half = verify(_seen(P["m300"], aliased=True, flash_scale=0.5), P["m300"]).terms["physics"]
    assert TERM_FLOOR < half < full


def test_the_classifier_term_is_bounded_and_only_for_its_own_classes() -> None:
    probs = {"m600": 0.0, "m300": 1.0, "phantom4": 0.0, "bird": 0.0, "none": 0.0}
    assert verify({}, P["m300"], probs).terms == {"classifier": CLASSIFIER_CLIP}
    assert verify({}, P["m600"], probs).terms == {"classifier": -CLASSIFIER_CLIP}
    uniform = {"m600": 1 / 3, "m300": 1 / 3, "phantom4": 1 / 3, "bird": 0.0, "none": 0.0}
    assert verify({}, P["m300"], uniform).terms["classifier"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("claim", ["m300", "m600"])
def test_a_classifier_that_gives_no_number_counts_against_the_claim(claim: str) -> None:
    """Fail closed: a NaN probability (a broken bundle) takes the classifier term to -clip, calibrated
    or not, where clipping NaN would have made it +clip."""
    from signatures.classify.calibration import CLASSIFIER_CLIP as CALIBRATION_CLIP, Calibration

    probs = {"m600": math.nan, "m300": math.nan, "phantom4": 0.0, "bird": 0.0, "none": 0.0}
    assert verify({}, P[claim], probs).terms == {"classifier": -CLASSIFIER_CLIP}
    cal = verify({}, P[claim], probs, calibration=Calibration(coef=(1.0, 0.0, 1.0), intercept=0.0))
    assert cal.terms["classifier"] == -CALIBRATION_CLIP and cal.llr < 0  # the calibration's own clip


def test_outside_the_open_set_the_classifier_only_counts_against_the_claim() -> None:
    """An airframe no enrolled profile explains (open set: unknown): the closed-set classifier's
    confidence in the claimed class is no evidence for it, its doubt still counts."""
    probs = {"m600": 0.0, "m300": 1.0, "phantom4": 0.0, "bird": 0.0, "none": 0.0}
    assert verify({}, P["m300"], probs, known=False).terms == {"classifier": 0.0}
    assert verify({}, P["m600"], probs, known=False).terms == {"classifier": -CLASSIFIER_CLIP}
    physics = verify(_seen(P["m300"]), P["m300"], probs, WIDE_MAX_TIP, known=False)
    assert physics.terms["classifier"] == 0.0 and physics.llr == physics.terms["physics"] > 0.0


def test_a_profile_registered_from_its_parameters_verifies_without_retraining() -> None:
    """A profile no bundle knows: the classifier says nothing about it, the physics does."""
    octo = UavProfile(slug="octo-x", name="Octo X", rotors=8, arms=8, blade_length_m=0.38,
                      rotor_rate_hz=45.0, propeller_distance_m=1.2)
    probs = {"m600": 0.6, "m300": 0.3, "phantom4": 0.1, "bird": 0.0, "none": 0.0}
    v = verify(_seen(octo, 1.1), octo, probs, max_tip_mps=WIDE_MAX_TIP)
    assert set(v.terms) == {"physics"} and v.llr > 0
    assert verify(_seen(P["phantom4"]), octo, probs, max_tip_mps=WIDE_MAX_TIP).llr < 0


def test_an_unreliable_rate_abstains() -> None:
    assert verify({**_seen(P["m300"]), "flash_score": 0.5}, P["m300"]).terms == {}
    assert verify({**_seen(P["m300"]), "flash_rate_hz": 0.0}, P["m300"]).terms == {}


def test_a_long_dwells_rate_is_read_from_the_score_that_detects_it() -> None:
    """A long dwell's envelope-spectrum rate (marked by its visible-rotor count) is a train from the
    CW detection's score, where the period search's needs 1: at 0.5 the long dwell's is read and
    verifies, the short dwell's abstains; under the detection's score both abstain."""
    from signatures.dsp.flash_spectrum import SPECTRAL_DETECT_SCORE
    from signatures.classify.verify import MIN_FLASH_SCORE, MIN_SPECTRAL_SCORE, min_flash_score

    assert MIN_SPECTRAL_SCORE == SPECTRAL_DETECT_SCORE < MIN_FLASH_SCORE
    long_dwell = {**_seen(P["m300"]), **_visible(4.0)}
    assert min_flash_score(long_dwell) == MIN_SPECTRAL_SCORE and min_flash_score(_seen(P["m300"])) == MIN_FLASH_SCORE
    assert verify({**long_dwell, "flash_score": 0.5}, P["m300"]).terms["physics"] > 1.0
    assert verify({**_seen(P["m300"]), "flash_score": 0.5}, P["m300"]).physics_abstained
    assert verify({**long_dwell, "flash_score": 0.3}, P["m300"]).physics_abstained


finite = st.floats(min_value=0.0, max_value=1e6, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(f=finite, f_std=finite, tip=finite, tip_std=finite, score=finite, aliased=st.booleans(),
       p=st.floats(0.0, 1.0), slug=st.sampled_from(sorted(P)), rotors=finite, rotors_std=finite)
def test_any_estimate_gives_a_finite_bounded_score(f, f_std, tip, tip_std, score, aliased, p, slug, rotors,
                                                   rotors_std) -> None:
    feats = {"flash_rate_hz": f, "flash_rate_std_hz": f_std, "tip_speed_mps": tip, "tip_speed_std_mps": tip_std,
             "flash_score": score, "tip_aliased": float(aliased), "rotors_seen": rotors, "rotors_seen_std": rotors_std}
    v = verify(feats, P[slug], {slug: p, "other": 1.0 - p}, max_tip_mps=WIDE_MAX_TIP)
    assert math.isfinite(v.llr)
    assert TERM_FLOOR - CLASSIFIER_CLIP <= v.llr <= 10.0


ESTIMATES = ("flash_rate_hz", "flash_rate_std_hz", "tip_speed_mps", "tip_speed_std_mps", "flash_score", "tip_aliased",
             "rotors_seen", "rotors_seen_std", "rotors_lower_bound")


@settings(max_examples=300, deadline=None)
@given(values=st.lists(st.floats(), min_size=len(ESTIMATES), max_size=len(ESTIMATES)), p=st.floats(),
       slug=st.sampled_from(sorted(P)), known=st.booleans())
def test_no_input_makes_the_score_nan_or_lets_garbage_support_the_claim(values, p, slug, known) -> None:
    """Any estimates (NaN, infinities, negatives) and any classifier output: the LLR is a bounded
    number, and a probability that is no probability counts as far against the claim as it can."""
    v = verify(dict(zip(ESTIMATES, values)), P[slug], {slug: p, "other": 0.0}, max_tip_mps=WIDE_MAX_TIP, known=known)
    assert not math.isnan(v.llr) and TERM_FLOOR - CLASSIFIER_CLIP <= v.llr <= 10.0
    assert all(not math.isnan(t) for t in v.terms.values())
    if not 0.0 <= p <= 1.0:
        assert v.terms["classifier"] == -CLASSIFIER_CLIP


@settings(max_examples=100, deadline=None)
@given(scale=st.floats(0.82, 1.18), cos_el=st.floats(0.5, 1.0), slug=st.sampled_from(sorted(P)))
def test_the_physics_of_a_genuine_return_never_contradicts_its_claim(scale: float, cos_el: float, slug: str) -> None:
    """Whatever rotor rate it flies (within the band) and whatever elevation, a clean genuine
    return's physics favours its claim, with or without the rotors it shows (one pair of its
    rotors flashing together: one fewer seen)."""
    assert verify(_seen(P[slug], scale, cos_el), P[slug], max_tip_mps=WIDE_MAX_TIP).llr > 0
    rotors = P[slug].rotors - 1 if P[slug].rotors > 4 else P[slug].rotors
    seen = {**_seen(P[slug], scale, cos_el), **_rotors(rotors, 4 * rotors)}
    assert verify(seen, P[slug], max_tip_mps=WIDE_MAX_TIP).llr > 0


def test_an_extreme_blade_ratio_is_reported_finite() -> None:
    """Tips of 1e300 m/s against a flash rate of 1e-300 Hz (found by the property test above):
    the score and the reported ratio stay finite, and the JSON encodes."""
    import json

    feats = {"flash_rate_hz": 1e-300, "flash_rate_std_hz": 1e-301, "tip_speed_mps": 1e300, "tip_speed_std_mps": 1e299,
             "flash_score": 5.0, "tip_aliased": 0.0}
    v = verify(feats, P["m300"], max_tip_mps=WIDE_MAX_TIP)
    assert math.isfinite(v.llr) and math.isfinite(v.compared["blade_ratio"]["measured"])
    json.dumps(v.to_json(), allow_nan=False)


def test_site_bands_default_to_todays_and_narrow_or_widen_with_site_data() -> None:
    """No site bands: verify is today's (the shipped bundle's decisions unchanged). Site bands:
    each edge shrunk from today's band toward the site's own spread (10 pseudo-recordings of prior);
    a card's bands read back; too few recordings keep the prior."""
    import math

    from signatures.train.site_bands import BAND_PRIOR_WEIGHT, shrunk_band
    from signatures.profiles import shipped_profiles
    from signatures.classify.verify import RATE_BAND, ROTOR_BAND, Bands, bands_from, verify

    prof = shipped_profiles()["m300"]
    feats = {"flash_rate_hz": prof.blade_flash_rate_hz * 1.1, "flash_rate_std_hz": 1.0, "flash_score": 5.0,
             "rotors_seen": 3.5, "rotors_seen_std": 0.5}
    assert verify(feats, prof) == verify(feats, prof, bands=None) == verify(feats, prof, bands=Bands())
    assert Bands() == Bands(RATE_BAND, ROTOR_BAND)
    tight = [math.log(1.0 + 0.01 * k) for k in range(-5, 6)] * 3  # 33 site ratios within +-5 %
    lo, hi = shrunk_band(tight, RATE_BAND)
    assert RATE_BAND[0] < lo < 0.96 and 1.04 < hi < RATE_BAND[1]
    w = BAND_PRIOR_WEIGHT / (BAND_PRIOR_WEIGHT + len(tight))
    site_lo = math.log(0.96) - (math.log(1.04) - math.log(0.96)) / 8  # q10 less 1/8 of the q10-q90 span
    assert math.isclose(math.log(lo), w * math.log(RATE_BAND[0]) + (1 - w) * site_lo, rel_tol=0.1)
    wide = [math.log(0.4 + 0.02 * k) for k in range(30)]  # rotors read low on this site
    assert shrunk_band(wide, ROTOR_BAND)[0] < ROTOR_BAND[0]
    assert shrunk_band(tight[:4], RATE_BAND) == RATE_BAND
    narrowed = Bands(rate=(lo, hi))
    assert verify(feats, prof, bands=narrowed).terms["physics"] != verify(feats, prof).terms["physics"]
    assert bands_from({"m300": {"rate": [lo, hi], "rotors": list(ROTOR_BAND)}}, "m300") == narrowed
    assert bands_from(None, "m300") is None and bands_from({"m600": {"rate": [1, 2], "rotors": [1, 2]}}, "m300") is None


def test_a_group_of_one_is_the_claim_alone() -> None:
    """`also` naming only the claimed model (or nothing) changes neither the terms nor the LLR."""
    seen = {**_seen(P["m300"], 1.05, aliased=True), **_rotors(3.8, 8)}
    probs = {"m300": 0.6, "m600": 0.3, "phantom4": 0.1}
    alone = verify(seen, P["m300"], probs, max_tip_mps=22.0)
    assert verify(seen, P["m300"], probs, max_tip_mps=22.0, also=[(P["m300"], None)]) == alone
    assert alone.verified_as == () and "verified_as" not in alone.to_json()


def test_a_confusable_group_carries_what_radar_can_tell() -> None:
    """An M300 at 0.92 of its rate flashes where an M600 would at 1.0: the classifier splits its
    mass between the two. Against the M300 alone the return is doubtful; against "an M300 or an
    M600" it is consistent, and a Phantom 4 still is not."""
    seen = {**_seen(P["m300"], 0.92, aliased=True), **_rotors(4.6, 8)}
    probs = {"m300": 0.48, "m600": 0.47, "phantom4": 0.05}
    alone = verify(seen, P["m300"], probs, max_tip_mps=22.0)
    group = verify(seen, P["m300"], probs, max_tip_mps=22.0, also=[(P["m600"], None)])
    assert group.verified_as == ("m300", "m600") and group.to_json()["verified_as"] == ["m300", "m600"]
    # the classifier: 0.95 of the mass on a group holding 2 of 3 classes, against 0.48 on one of 3
    assert group.terms["classifier"] == pytest.approx(math.log(0.95 / 0.05) - math.log(2.0), abs=1e-6)
    assert alone.terms["classifier"] == pytest.approx(math.log(0.48 / 0.52) - math.log(0.5), abs=1e-6)
    assert group.llr > alone.llr + 1.0
    # the physics term: the log of the mean of the members' likelihood ratios
    m300 = verify(seen, P["m300"], max_tip_mps=22.0).terms["physics"]
    m600 = verify(seen, P["m600"], max_tip_mps=22.0).terms["physics"]
    assert group.terms["physics"] == pytest.approx(math.log((math.exp(m300) + math.exp(m600)) / 2), abs=1e-9)
    assert min(m300, m600) <= group.terms["physics"] <= max(m300, m600)
    # a Phantom 4 (117 Hz) claiming the M300 with the M600 beside it: neither member fits
    p4 = {**_seen(P["phantom4"], aliased=True), **_rotors(3.9, 8)}
    assert verify(p4, P["m300"], {"phantom4": 0.9, "m300": 0.05, "m600": 0.05}, max_tip_mps=22.0,
                  also=[(P["m600"], None)]).llr < -4.0


def test_a_group_of_every_class_leaves_the_classifier_out() -> None:
    seen = _seen(P["m300"], aliased=True)
    probs = {"m300": 0.4, "m600": 0.3, "phantom4": 0.2, "bird": 0.1}
    v = verify(seen, P["m300"], probs, max_tip_mps=22.0, also=[(P["m600"], None), (P["phantom4"], None)])
    assert set(v.terms) == {"physics"} and v.verified_as == ("m300", "m600", "phantom4")


def test_a_group_abstains_with_its_claim() -> None:
    """No usable rate: no physics term for the group either, so the classifier cannot carry it."""
    seen = {**_seen(P["m300"], aliased=True), "flash_score": 0.2}
    v = verify(seen, P["m300"], {"m300": 0.5, "m600": 0.45, "phantom4": 0.05}, max_tip_mps=22.0,
               also=[(P["m600"], None)])
    assert v.physics_abstained and "classifier" in v.terms
