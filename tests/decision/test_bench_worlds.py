"""`authn bench` in two worlds: the equal error rate, the verification score, the --world
option, a tiny two-world run, and the tables at 80 columns."""

from __future__ import annotations

import json
import math
from statistics import NormalDist

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lab.bench.verification import UNVERIFIED, eer, roc, verification_score
from tests.lab_plugin import needs_lab

scores = st.lists(st.integers(-20, 20), min_size=1, max_size=40)  # integers: ties happen, maps stay strict


def test_eer_of_a_small_sample_by_hand() -> None:
    """Accept at >= t. At t = 0.7: FAR 1/3, FRR 1/4; at t = 0.8: FAR 0, FRR 1/4; the segment
    between them meets FAR = FRR at 1/4."""
    assert eer([0.6, 0.8, 0.9, 1.0], [0.1, 0.2, 0.7]) == pytest.approx(0.25)
    far, frr = roc([0.6, 0.8, 0.9, 1.0], [0.1, 0.2, 0.7])
    assert (far[0], frr[0], far[-1], frr[-1]) == (1.0, 0.0, 0.0, 1.0)
    assert np.all(np.diff(far) <= 0) and np.all(np.diff(frr) >= 0)


def test_eer_of_two_gaussians_is_phi_of_half_the_separation() -> None:
    """Genuine N(d, 1) against impostor N(0, 1): the threshold d/2 gives FAR = FRR = Phi(-d/2)."""
    rng = np.random.default_rng(0)
    for d in (0.5, 2.0, 3.0):
        got = eer(rng.normal(d, 1.0, 200_000), rng.normal(0.0, 1.0, 200_000))
        assert got == pytest.approx(NormalDist().cdf(-d / 2), abs=0.004)


def test_eer_extremes() -> None:
    assert eer([0.9, 1.0], [0.0, 0.1]) == 0.0
    assert eer([0.5] * 5, [0.5] * 7) == pytest.approx(0.5)
    assert eer([0.0, 0.1], [0.9, 1.0]) == 1.0  # a score that points the wrong way
    with pytest.raises(ValueError):
        eer([], [1.0])


@settings(max_examples=60, deadline=None)
@given(genuine=scores, impostor=scores)
def test_eer_is_invariant_under_monotone_maps_and_symmetric(genuine: list[int], impostor: list[int]) -> None:
    e = eer(genuine, impostor)
    assert 0.0 <= e <= 1.0
    assert eer([math.exp(x / 4) for x in genuine], [math.exp(x / 4) for x in impostor]) == pytest.approx(e)
    assert eer([-x for x in impostor], [-x for x in genuine]) == pytest.approx(e)  # roles swapped


def test_verification_score_is_the_checks_own_llr() -> None:
    radar = {"model": "m300", "verification": {"llr": 1.25, "terms": {"physics": 2.0, "classifier": -0.75}}}
    assert verification_score(radar) == 1.25
    assert verification_score({"model": "m300", "verification": {"llr": 0.0, "terms": {}}}) == UNVERIFIED
    assert verification_score({"model": "bird"}) == UNVERIFIED
    assert verification_score(None) == UNVERIFIED


def test_world_choice() -> None:
    from lab.bench.worlds import world_choice
    from core.errors import BadInput

    assert world_choice("both") == ("training", "heldout")
    assert world_choice("heldout") == ("heldout",)
    with pytest.raises(BadInput, match="--world"):
        world_choice("mars")


def test_two_worlds_check_the_same_claims() -> None:
    """One claim per category in each world: the pair of trials shares the scene (airframe,
    claim) and differs only by the renderer; a training-world spoof is not accepted (one unsigned
    dwell at the default targets reaches neither Wald bound: `inconclusive`, with the radar's
    evidence against the claim); the JSON view and the EERs cover every cell."""
    from lab.bench.worlds import WORLD_CATEGORIES, correct_rates, equal_error_rates, run_worlds, summarise_worlds
    from lab.heldout import unseen_profiles

    trials = run_worlds(("paper",), ("training", "heldout"), 1, seed=4, snrs=(10.0,))
    assert [(t.category, t.world) for t in trials] == [(c, w) for c in WORLD_CATEGORIES
                                                       for w in ("training", "heldout")]
    for a, b in zip(trials[::2], trials[1::2]):
        assert (a.flies, a.claims, a.snr_db) == (b.flies, b.claims, b.snr_db)
    by = {(t.category, t.world): t for t in trials}
    assert by[("unseen", "training")].flies in unseen_profiles()
    assert by[("type_spoof", "training")].flies != by[("type_spoof", "training")].claims
    spoof = by[("type_spoof", "training")]
    assert spoof.decision == "inconclusive" and "radar-inconclusive" in spoof.reasons
    assert all(math.isfinite(t.score) and t.radar_model is not None for t in trials)
    assert by[("genuine", "training")].score > 0 > by[("type_spoof", "training")].score
    assert len(correct_rates(trials)) == 6 and len(equal_error_rates(trials)) == 4
    doc = json.loads(json.dumps(summarise_worlds(trials)))
    assert set(doc["decisions"]["paper"]["10"]) == set(WORLD_CATEGORIES)
    assert doc["decisions"]["paper"]["10"]["genuine"]["heldout"]["n"] == 1
    assert set(doc["eer"]) == {f"paper/10/{c}/{w}" for c in ("type_spoof", "unseen") for w in ("training", "heldout")}


def test_summary_names_the_pairs_that_went_wrong() -> None:
    """Which airframe flew and which was claimed, counted over the wrong decisions only: where
    impostors pass is what the next estimator work needs to know."""
    from lab.bench.worlds import Trial, summarise_worlds

    def trial(flies: str, claims: str, decision: str) -> Trial:
        return Trial("wide", "heldout", 0.0, "type_spoof", flies, claims, decision, ("registered-active",),
                     flies, 1.0 if decision == "accept" else -1.0, 5.0, True)

    trials = [trial("m300", "m600", "accept"), trial("m300", "m600", "accept"), trial("m600", "m300", "accept"),
              trial("phantom4", "m300", "reject")]
    cell = summarise_worlds(trials)["decisions"]["wide"]["0"]["type_spoof"]["heldout"]
    assert cell["wrong_pairs"] == {"m300->m600": 2, "m600->m300": 1}
    assert cell["n"] == 4 and cell["correct_rate"] == 0.25


def test_summary_splits_claims_by_rotor_evidence() -> None:
    """A claim whose rotors were not seen rests on the classifier alone: the summary says how
    many were seen, and how many of those were decided right, so that a world's misses split
    into "nothing seen" and "seen but misjudged"."""
    from lab.bench.verification import eer, rotor_evidence
    from lab.bench.worlds import Trial, equal_error_rates, evidence_rates, summarise_worlds

    def trial(world: str, decision: str, seen: bool) -> Trial:
        return Trial("paper", world, 0.0, "genuine", "m300", "m300", decision, ("registered-active",), "m300",
                     1.0 if decision == "accept" else -1.0, 5.0, seen)

    trials = [trial("heldout", "accept", True), trial("heldout", "reject", True), trial("heldout", "reject", False),
              trial("heldout", "reject", False), trial("training", "reject", False)]
    rates = evidence_rates(trials)
    assert rates[("paper", 0.0, "genuine", "heldout")] == (0.5, 0.5)
    assert rates[("paper", 0.0, "genuine", "training")] == (0.0, None)
    cell = json.loads(json.dumps(summarise_worlds(trials)))["decisions"]["paper"]["0"]["genuine"]
    assert cell["heldout"]["rotor_evidence_rate"] == 0.5 and cell["heldout"]["correct_rate_with_rotor_evidence"] == 0.5
    assert cell["training"]["correct_rate_with_rotor_evidence"] is None
    # the EER among the claims whose rotors were not seen: the classifier's separation alone
    spoofs = [Trial("paper", "heldout", 0.0, "type_spoof", "m600", "m300", "reject", ("radar-not-a-drone",), "bird",
                    s, 5.0, False) for s in (-1.0, 2.0)]
    blind = equal_error_rates(trials + spoofs, rotor_evidence=False)
    assert set(blind) == {("paper", 0.0, "type_spoof", "heldout")}  # the training world has no spoofs here
    assert blind[("paper", 0.0, "type_spoof", "heldout")] == eer([-1.0, -1.0], [-1.0, 2.0])
    doc = json.loads(json.dumps(summarise_worlds(trials + spoofs)))
    assert doc["eer_without_rotor_evidence"] == {"paper/0/type_spoof/heldout": round(eer([-1.0, -1.0], [-1.0, 2.0]), 4)}
    # read from a check's radar evidence: the physics term ran, or only the classifier's did
    assert rotor_evidence({"verification": {"llr": 1.0, "terms": {"physics": 2.0, "classifier": -1.0}}})
    assert not rotor_evidence({"verification": {"llr": -1.0, "terms": {"classifier": -1.0}}})
    assert not rotor_evidence(None) and not rotor_evidence({"model": "bird"})


@needs_lab
def test_cli_world_option(tmp_path, capsys) -> None:
    from authn.cli import main

    assert main(["bench", "--worlds-only", "--world", "heldout", "--n", "1", "--preset", "paper", "--snr", "20",
                 "--json", "--plot", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    cells = doc["worlds"]["decisions"]["paper"]["20"]
    assert all(set(c) == {"heldout"} for c in cells.values())
    assert all(0.0 <= c["heldout"]["rotor_evidence_rate"] <= 1.0 for c in cells.values())
    assert (tmp_path / "det-paper.png").stat().st_size > 10_000
    assert main(["bench", "--worlds-only", "--world", "mars", "--n", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--world" in err and len(err.splitlines()) == 1


def _render(table) -> str:
    from rich.console import Console

    console = Console(width=80, record=True, color_system=None)
    console.print(table)
    return console.export_text()


def _fits(text: str, values: list[str]) -> None:
    assert "…" not in text and "..." not in text  # nothing truncated
    assert max(len(line) for line in text.splitlines()) <= 80
    for v in values:
        assert v in text, v


def test_bench_tables_fit_80_columns() -> None:
    from lab.bench.decisions import CATEGORIES, EXPECTED, Row
    from lab.bench.pareto import Point
    from lab.bench.tables import (decision_table, eer_table, evidence_table, imports_table, pareto_table,
                                    stage_table, worlds_table)
    from lab.bench.worlds import Trial

    rows = [Row(p, c, 300, 299, 300, 1234.5, {}) for p in ("paper", "wide") for c in CATEGORIES]
    _fits(_render(decision_table(rows, 300, EXPECTED)), ["position_spoof", "drip_replayed", "99.7%", "1234.5"])
    names = ["gated + ensemble (default)", "gated, quick tier (paper's 11 + gate physics) + RF",
             "gated, first 1/4 of the dwell, quick tier + RF", "gated, float64 features + ensemble"]
    pts = [Point(nm, 155.43, {0.0: 0.992, 10.0: 1.0, 20.0: 0.815}, 0.013, i % 2 == 0) for i, nm in enumerate(names)]
    _fits(_render(pareto_table("wide", pts, 2.72, (0.0, 10.0, 20.0))), ["155.43", "57.1", "0.992", "0.815", "0.013"])
    st_ = {"checks": 70, "stage_median_ms": {"read": 2.244, "radar_features": 24.061, "policy_registry": 0.31}}
    _fits(_render(stage_table("wide", st_, {"fft_ms": 2.72})), ["24.061", "2.720", "policy_registry"])
    _fits(_render(imports_table({"authn.check": 182.0, "onnxruntime": 156.0})), ["authn.check", "182"])
    trials = [Trial(p, w, s, c, "m300", "m300", "accept", ("registered-active",), "m300", 0.5 + 0.1 * i, 10.0,
                    w == "training")
              for p in ("paper", "wide") for s in (0.0, 10.0) for i, c in enumerate(("genuine", "type_spoof", "unseen"))
              for w in ("training", "heldout")]
    _fits(_render(worlds_table(trials)), ["type spoof", "unseen", "100.0%", "0.0%", "held-out sim"])
    _fits(_render(evidence_table(trials)), ["type spoof", "100% / 0%", "0% / -", "held-out sim"])
    _fits(_render(eer_table(trials)), ["type spoof", "0.0%", "training sim"])


@needs_lab
def test_cli_seeds_pool_the_claims(capsys) -> None:
    """--seeds K runs the claims of K consecutive seeds and pools them (K x n per cell)."""
    from authn.cli import main

    assert main(["bench", "--worlds-only", "--world", "training", "--n", "1", "--seeds", "2", "--preset", "paper",
                 "--snr", "20", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["seeds"] == [7, 8] and doc["n_per_category"] == 2
    assert doc["worlds"]["decisions"]["paper"]["20"]["genuine"]["training"]["n"] == 2


@needs_lab
def test_cli_seeds_below_one_is_bad_input(capsys) -> None:
    """Exit 2, one line naming the option (typer's range check, reported by `main`)."""
    from authn.cli import main

    assert main(["bench", "--worlds-only", "--seeds", "0", "--n", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ")
    assert "--seeds" in err and "0 is not in the range x>=1" in err  # click's IntRange (typer < 0.26)
