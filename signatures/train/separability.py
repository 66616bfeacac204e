"""What an enrolment's cross-validated claims say the radar can separate: per pair of models, the
single-dwell and track-level false accepts (tracks drawn from the dwell scores and decided by the
check's own sequential test), which pairs are radar-confusable and so which claims need a DRIP
signature, and the verification threshold at a false-accept target."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

#: A pair whose cross-validated pairwise false-accept rate exceeds this is radar-confusable.
CONFUSABLE_ERROR = 0.01
#: Fewest cross-validated claims (both directions) that can show a pair separable: with none of
#: them accepted, the pair's false-accept rate is below 10 % at 95 % confidence (the zero-failure
#: bound, 1 - 0.9 ** n >= 0.95); a pair with fewer is radar-confusable whatever its rate.
MIN_SEPARABLE_CLAIMS = math.ceil(math.log(1.0 - 0.95) / math.log(1.0 - 0.10))
#: Genuine acceptance the score calibration must add, on the site's cross-validated claims, before
#: `authn models enrol` applies it unasked (fixed a priori: a gain the folds' noise does not make).
CALIBRATION_GAIN = 0.05
#: The longest track a site decides on (`authn check --track` in the must-show: up to 8 dwells),
#: and how many tracks are drawn per (flown, claimed) pair for its track-level errors.
TRACK_DWELLS = 8
TRACK_DRAWS = 400


#: A dwell's cross-validated verification as a track uses it: (LLR, physics term present), or
#: None when nothing was verified (no term: the track adds nothing for it, `authn.track`).
DwellScore = tuple[float, bool] | None


def track_rates(dwells: Sequence[DwellScore], walk: Callable[[Sequence[tuple[float, bool]]], tuple[str, int]],
                length: int = TRACK_DWELLS, draws: int = TRACK_DRAWS, seed: int = 0) -> tuple[float, int, int]:
    """(accepted share, tracks, dwells per track) of `draws` tracks of `length` dwells, each
    drawn without replacement from one (flown, claimed) pair's cross-validated dwell scores and
    decided by `walk` (`authn.sprt.Sprt.walk`: the check's own combination and bounds). An
    inconclusive track is not accepted, as at the end of a real track. Fewer scores than
    `length`: tracks of all of them (the card says how long)."""
    if not dwells:
        return float("nan"), 0, 0
    rng = np.random.default_rng([seed, len(dwells), 91])
    n = min(length, len(dwells))
    accepted = 0
    for _ in range(draws):
        pick = rng.choice(len(dwells), size=n, replace=False)
        track = [d for d in (dwells[j] for j in pick) if d is not None]
        accepted += walk(track)[0] == "accept"
    return accepted / draws, draws, n


def separation(genuine: Sequence[float], impostor: dict[tuple[str, str], list[float]],
                dwells: dict[tuple[str, str], list[DwellScore]], enrolled: Sequence[str], sprt: Any,
                seed: int) -> dict[str, Any]:
    """How one scoring of the cross-validated claims separates them at the level checks decide at:
    with a sequential test, the mean over enrolled models of genuine tracks accepted and the worst
    pair's type-spoof tracks accepted (`track_rates`); without one, single dwells at LLR >= 0."""
    if sprt is not None:
        level = "tracks"
        gen = [track_rates(dwells.get((m, m), []), sprt.walk, seed=seed)[0] for m in enrolled]
        fa = [track_rates(v, sprt.walk, seed=seed)[0] for k, v in dwells.items() if k[0] != k[1]]
    else:
        level = "single_dwell"
        gen = [float(np.mean(np.asarray(genuine) >= 0.0))] if len(genuine) else []
        fa = [float(np.mean(np.asarray(v) >= 0.0)) for v in impostor.values() if len(v)]
    gen, fa = [g for g in gen if not math.isnan(g)], [f for f in fa if not math.isnan(f)]
    return {"level": level, "genuine_accept": mean_or_none(gen), "worst_pair_false_accept": max(fa) if fa else None}


def calibration_pays(choice: dict[str, dict[str, Any]]) -> bool:
    """Apply the score calibration where the site's own cross-validated claims say it pays: genuine
    acceptance up by at least `CALIBRATION_GAIN` and the worst pair's false accepts no higher than
    uncalibrated (or than `CONFUSABLE_ERROR`, whichever is larger). A tie keeps the uncalibrated
    score: the verification every other bundle uses."""
    u, c = choice["uncalibrated"], choice["calibrated"]
    if u["genuine_accept"] is None or c["genuine_accept"] is None:
        return False
    fa_u, fa_c = u["worst_pair_false_accept"] or 0.0, c["worst_pair_false_accept"] or 0.0
    return c["genuine_accept"] >= u["genuine_accept"] + CALIBRATION_GAIN and fa_c <= max(fa_u, CONFUSABLE_ERROR)


def mean_or_none(v: Sequence[float]) -> float | None:
    return round(float(np.mean(v)), 4) if len(v) else None


def rate_or_none(x: float) -> float | None:
    return None if math.isnan(x) else round(x, 6)


def pair_cards(enrolled: Sequence[str], det_counts: dict[str, int], n_oth: dict[str, int], cm: np.ndarray,
           called: dict[tuple[str, str], int], index: dict[str, int], impostor: dict[tuple[str, str], list[float]],
           dwell_scores: dict[tuple[str, str], list[DwellScore]], sprt: Any, seed: int) -> list[dict[str, Any]]:
    """The card's pairs: each two enrolled models, and each enrolled model against each profile
    simulated in the waveform (`simulated`: that profile); the classifier's confusion rate from the
    cross-validated confusion matrix `cm` (rows: enrolled) and `called` (simulated b called a)."""
    pairs: list[dict[str, Any]] = []
    for i, a in enumerate(enrolled):
        for b in enrolled[i + 1:]:
            conf = int(cm[i, index[b]] + cm[enrolled.index(b), index[a]])
            pairs.append(_pair(a, b, impostor, conf / (det_counts[a] + det_counts[b]), dwell_scores, sprt, seed))
        for b, n in n_oth.items():
            conf = int(cm[i, index[b]]) + called[(b, a)]
            pairs.append({**_pair(a, b, impostor, conf / (det_counts[a] + n), dwell_scores, sprt, seed),
                          "simulated": b})
    return pairs


def _pair(a: str, b: str, impostor: dict[tuple[str, str], list[float]], confusion: float,
          dwell_scores: dict[tuple[str, str], list[DwellScore]], sprt: Any, seed: int) -> dict[str, Any]:
    """One pair's card entry: its single-dwell false accepts at the applied threshold (0 nats), both
    directions, the classifier's confusion rate, and its track-level false accepts."""
    fa = impostor.get((a, b), []) + impostor.get((b, a), [])
    n_fa = sum(v >= 0.0 for v in fa)
    return {"models": [a, b], "single_dwell": {
        "false_accept_rate": round(n_fa / len(fa), 6) if fa else None, "false_accepts": n_fa, "claims": len(fa),
        "classifier_confusion_rate": round(confusion, 6)}, "tracks": _pair_tracks(dwell_scores, a, b, sprt, seed),
        "separation": _separation_nats(dwell_scores, a, b, sprt)}


def _separation_nats(dwell_scores: dict[tuple[str, str], list[DwellScore]], a: str, b: str,
                     sprt: Any) -> dict[str, Any] | None:
    """As a shipped card's `separation`: the mean capped increment (`Sprt.increment`) of a genuine
    dwell of `a` and of a type-spoof dwell between a and b (both directions), and the dwells each
    takes to decide (`Sprt.dwells_to_decide`; None: never)."""
    if sprt is None:
        return None

    def mean(scores: list[DwellScore]) -> float | None:
        inc = [sprt.increment(llr, physics) for llr, physics in (d for d in scores if d is not None)]
        return round(float(np.mean(inc)), 3) if inc else None

    g = mean(dwell_scores.get((a, a), []))
    i = mean(dwell_scores.get((a, b), []) + dwell_scores.get((b, a), []))
    return {"genuine_nats_per_dwell": g, "impostor_nats_per_dwell": i,
            "dwells_to_accept": None if g is None else sprt.dwells_to_decide(g),
            "dwells_to_reject": None if i is None else sprt.dwells_to_decide(i)}


def signatures_needed(enrolled: Sequence[str], single: Sequence[Sequence[str]],
                tracks: Sequence[Sequence[str]] | None) -> dict[str, dict[str, Any]]:
    """Which claims need a DRIP signature: per enrolled model, the models radar cannot tell it
    from (single dwells; tracks), so that its unsigned claims are rejected wherever one of them is
    registered at the site too (`radar-confusable-unsigned`)."""
    def partners(pairs: Sequence[Sequence[str]], m: str) -> list[str]:
        return sorted({x for p in pairs if m in p for x in p if x != m})

    return {m: {"single_dwell": partners(single, m), "tracks": None if tracks is None else partners(tracks, m),
                "note": "unsigned claims of this model are rejected where one of these is registered at the site"}
            for m in enrolled}


def _pair_tracks(dwell_scores: dict[tuple[str, str], list[DwellScore]], a: str, b: str, sprt: Any,
                 seed: int) -> dict[str, Any] | None:
    """The pair's track-level false accepts: tracks of a claimed as b and of b claimed as a."""
    if sprt is None:
        return None
    ab = track_rates(dwell_scores.get((a, b), []), sprt.walk, seed=seed)
    ba = track_rates(dwell_scores.get((b, a), []), sprt.walk, seed=seed)
    claims = ab[1] + ba[1]
    fa = ab[0] * ab[1] + ba[0] * ba[1] if claims else float("nan")
    return {"false_accept_rate": rate_or_none(fa / claims) if claims else None,
            "false_accepts": int(round(fa)) if claims else 0, "claims": claims,
            "dwells": min(ab[2], ba[2]), "recordings": len(dwell_scores.get((a, b), [])) +
            len(dwell_scores.get((b, a), []))}


def single_confusable(pair: dict[str, Any]) -> bool:
    """Radar-confusable for single-dwell checks: the cross-validated false-accept rate above the
    line, or too few claims (`MIN_SEPARABLE_CLAIMS`) to show it below."""
    sd = pair["single_dwell"]
    if sd["claims"] < MIN_SEPARABLE_CLAIMS:
        return True
    return sd["false_accept_rate"] is not None and sd["false_accept_rate"] > CONFUSABLE_ERROR


def track_confusable(pair: dict[str, Any]) -> bool:
    """Radar-confusable for track checks: the track-level false-accept rate above the line, or,
    where tracks could not reach `TRACK_DWELLS` dwells (too few recordings), the single-dwell verdict.
    Drawn tracks reuse the same recordings, so too few claims is confusable at this level too."""
    t, sd = pair.get("tracks"), pair["single_dwell"]
    if not t or t["false_accept_rate"] is None or t["dwells"] < TRACK_DWELLS or sd["claims"] < MIN_SEPARABLE_CLAIMS:
        return single_confusable(pair)
    return t["false_accept_rate"] > CONFUSABLE_ERROR


def threshold_at(impostor: dict[tuple[str, str], list[float]], target: float) -> float | None:
    """Lowest LLR threshold (accept at >= t) with an impostor false-accept rate <= target."""
    scores = np.sort(np.concatenate([np.asarray(v) for v in impostor.values()])) if impostor else np.array([])
    if not len(scores):
        return None
    allowed = int(math.floor(target * len(scores)))  # impostors that may still reach t
    return float(np.nextafter(scores[len(scores) - 1 - allowed], np.inf))

