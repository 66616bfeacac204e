"""The track accuracy bench's rule of which (flown, claimed) pairs the physics can separate, and its
offline sequential test against authn.track's (lab/bench/track_accuracy.py)."""

from __future__ import annotations

import numpy as np

from authn.track import Sprt
from lab.bench.track_accuracy import (OUT_OF_REACH, TrackResult, _variant_llr, _walk, all_profiles,
                                       track_accuracy_table, pairs, separable, spread_table, term_icc, term_icc_table,
                                       term_increments, walk_terms, what_if_pair_table)


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


def _track(world: str, cat: str, flies: str, claims: str, decision: str) -> TrackResult:
    return TrackResult(world, 10.0, cat, flies, claims, [] if cat == "genuine" else ["rotors"], decision, [], 3, 75,
                       0.0, 0.0)


def test_pairs_shown_out_of_reach_are_reported_apart_never_dropped() -> None:
    assert ("m600", "m300") in OUT_OF_REACH["heldout"] and "training" not in OUT_OF_REACH
    results = [_track("heldout", "type_spoof", "m600", "m300", "accept"),
               _track("heldout", "type_spoof", "m600", "phantom4", "reject"),
               _track("training", "type_spoof", "m600", "m300", "reject")]
    rows = [r for r in track_accuracy_table(results) if "type spoof" in r]
    held = [r for r in rows if r.startswith("| heldout")]
    assert len(held) == 2 and "| 2 | 50.0 % |" in held[0]  # the whole row, the failing pair counted
    assert "(pairs in reach)" in held[1] and "| 1 | 100.0 % |" in held[1]
    assert len([r for r in rows if r.startswith("| training")]) == 1  # nothing to report apart there


def test_the_spread_table_bins_dwells_by_the_rotors_rate_spread() -> None:
    def dwell(spread: float, read: float | None) -> dict:
        return {"world": "heldout", "snr_db": 10.0, "true_rate_spread": spread, "true_flash_rate_hz": 100.0,
                "flash_rate_hz": read or 0.0, "terms": {"rate": None if read is None else 1.0}}

    rows = [dwell(0.01, 101.0), dwell(0.03, 60.0), dwell(0.05, 104.0), dwell(0.09, None), dwell(0.12, 99.0),
            {"world": "heldout", "snr_db": 10.0, "decision": "reject"}]  # a dwell the radar saw nothing in
    line = spread_table(rows)[-1]
    assert line == "| heldout | 10 | 2, 50.0 % | 1, 100.0 % | 2, 50.0 % |"  # an abstained rate is not right


def test_the_true_rate_what_if_reads_the_flown_rate() -> None:
    row = {"flash_rate_hz": 61.0, "flash_rate_std_hz": 0.6, "flash_score": 0.0, "tip_aliased": 1.0,
           "rotors_seen": 0.0, "rotors_seen_std": 0.0, "claims": "phantom4", "true_rotor_rate_hz": 58.0,
           "terms": {"classifier": -1.0}}
    read, phys = _variant_llr(row, {}, 3.0, True)
    assert (read, phys) == (-1.0, False)  # a flash score of 0: the rate abstains, the classifier is all
    right, phys = _variant_llr(row, {}, 3.0, True, true_rate=True)
    assert phys and right - (-1.0) > 1.9  # 116 Hz against the claim's 116.7 Hz: the band's full support
    impostor, _ = _variant_llr({**row, "true_rotor_rate_hz": 40.0}, {}, None, True, true_rate=True)
    assert impostor < -3.0  # an M300's 80 Hz against the same claim


def test_the_what_if_per_pair_walks_each_scene_under_each_variant() -> None:
    dwell = {"world": "heldout", "snr_db": 10.0, "category": "genuine", "flies": "phantom4", "claims": "phantom4",
             "flash_rate_hz": 61.0, "flash_rate_std_hz": 0.6, "flash_score": 3.0, "tip_aliased": 1.0,
             "rotors_seen": 0.0, "rotors_seen_std": 0.0, "true_rotor_rate_hz": 58.0, "terms": {"classifier": -1.0}}
    rows = [{**dwell, "track": t} for t in range(2) for _ in range(12)]  # half-rate reads, a doubting classifier
    lines = what_if_pair_table(rows)
    assert lines[0].count("|") == 8 and len(lines) == 3
    # at half the rate the physics term is near 0; read right it is ~1.97 nats a dwell, which the
    # classifier's -1 holds under the accept bound's 1.38 a dwell (rho 0.2), and alone carries 12 dwells
    assert lines[2] == "| heldout | 10 | phantom4 -> phantom4 | 0/2 | 0/2 | 0/2 | 2/2 |"


def _rows(phys: list[list[float | None]], clf: list[list[float]]) -> list[dict]:
    """Diagnosis rows of one genuine pair: scene i's dwells with the given terms."""
    return [{"world": "heldout", "snr_db": 10.0, "category": "genuine", "flies": "m300", "claims": "m300",
             "track": i, "terms": {"physics": p, "classifier": k}}
            for i, (ps, ks) in enumerate(zip(phys, clf)) for p, k in zip(ps, ks)]


def test_the_icc_per_term_tells_a_repeated_bias_from_noise() -> None:
    rng = np.random.default_rng(0)
    bias = rng.normal(0.0, 1.0, 12)  # the classifier's error repeats within a scene, the physics' does not
    clf = [list(b + rng.normal(0.0, 0.2, 8)) for b in bias]
    phys = [list(rng.normal(1.0, 1.0, 8)) for _ in bias]
    rows = _rows(phys, clf)
    scenes = {("m300", "m300"): [[r for r in rows if r["track"] == i] for i in range(12)]}
    assert term_icc(scenes, "classifier", 4.0) > 0.8
    assert abs(term_icc(scenes, "physics", 4.0)) < 0.2
    table = term_icc_table(rows, boot=5)
    assert len(table) == 3 and "| heldout | 10 | genuine | 1 x 12 x 8 |" in table[2]


def test_per_term_increments_keep_the_cap_and_the_classifier_alone_rule() -> None:
    sprt = Sprt()
    rows = _rows([[3.0, None, None, -8.0, 1.0]], [[3.0, 2.5, -5.0, 3.0, -0.5]])
    incs = term_increments(rows, sprt.cap_nats)
    for (p, k), r in zip(incs, rows):
        t = r["terms"]
        llr = (t["physics"] or 0.0) + t["classifier"]
        assert np.isclose(p + k, sprt.increment(llr, t["physics"] is not None))
    assert incs[1] == (0.0, 0.0) and incs[2] == (0.0, -4.0)  # physics abstained: only against the claim


def test_per_term_walk_with_one_rho_is_the_track_test() -> None:
    rng = np.random.default_rng(1)
    sprt = Sprt()
    for _ in range(200):
        n = int(rng.integers(1, 30))
        phys = [float(x) if rng.random() > 0.2 else None for x in rng.normal(0.5, 2.5, n)]
        clf = [float(x) for x in rng.normal(0.0, 2.0, n)]
        incs = term_increments(_rows([phys], [clf]), sprt.cap_nats)
        dwells = [((p or 0.0) + k, p is not None) for p, k in zip(phys, clf)]
        assert walk_terms(incs, 0.2, 0.2) == sprt.walk(dwells)
    # a classifier part discounted as more repeated: the same dwells (2 nats a dwell) no longer
    # accept (at most 1 / 0.2 + 1 / 0.8 = 6.25 nats < 6.9)
    assert walk_terms([(1.0, 1.0)] * 10, 0.2, 0.2) == ("accept", 9)  # 18 / 2.6 = 6.92
    assert walk_terms([(1.0, 1.0)] * 10, 0.2, 0.8) == ("inconclusive", 10)
