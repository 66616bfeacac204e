"""The must-show bench's rule of which (flown, claimed) pairs the physics can separate, and its
offline sequential test against authn.track's (lab/bench/track_must_show.py)."""

from __future__ import annotations

from authn.track import Sprt
from lab.bench.track_must_show import _walk, all_profiles, pairs, separable


def test_the_rule_names_rate_and_rotor_separations() -> None:
    p = all_profiles()
    assert separable(p["m300"], p["m600"]) == ["rotors"]  # 80 and 73 Hz: inside each other's band; 4 vs 6
    assert separable(p["m300"], p["phantom4"]) == ["rate"]  # 80 vs 117 Hz, both 4 rotors
    assert separable(p["m600"], p["phantom4"]) == ["rate", "rotors"]
    assert separable(p["x8-coax"], p["phantom4"]) == ["rotors"]  # 96 Hz sits in the Phantom 4's band
    assert separable(p["m300"], p["m300"]) == []


def test_every_claim_of_the_bench_is_listed_once() -> None:
    got = pairs()
    assert len(got) == len(set((c, f, m) for c, f, m, _ in got)) == 3 + 6 + 4 * 3
    assert {c for c, *_ in got} == {"genuine", "type_spoof", "unseen"}
    assert all(f == m and not why for c, f, m, why in got if c == "genuine")


def test_the_offline_walk_stops_where_the_track_test_does() -> None:
    sprt = Sprt()
    assert _walk([(5.0, True)] * 10) == ("accept", 3)  # 4, 6.67, 8.57 nats: capped and discounted
    assert _walk([(-5.0, True)] * 10) == ("reject", 2)
    assert _walk([(5.0, False)] * 10) == ("inconclusive", 10)  # the classifier alone never carries a claim
    assert _walk([(1.0, True)] * 75)[0] == "inconclusive"  # mean below accept_nats * rho never accepts
    assert sprt.accept_nats * sprt.correlation > 1.0
