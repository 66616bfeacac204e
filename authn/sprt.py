"""Wald's sequential probability ratio test, as `authn check` decides one dwell and a track of many.

Bounds from the target error rates: with alpha (an impostor accepted) and beta (a genuine claim
rejected), accept at LLR >= log((1 - beta) / alpha), refute at LLR <= log(beta / (1 - alpha)).
Wald's rates hold for independent, calibrated increments; the dwells' verification LLRs are
neither, so each dwell counts at most `DWELL_CAP_NATS` either way, the sum is discounted for the
dwells' correlation (n dwells count as n / (1 + (n - 1) rho)), a dwell whose physics term
abstained counts only against the claim, a dwell that moves no sum (nothing for or against the
claim, as such a dwell's with the classifier for it) is no observation and leaves n alone, and
increments given per alternative are summed per alternative, the least sum counting
(docs/tracks.md). A single check is a track of one dwell: the policy gets the same `record`
(docs/policies.md). Math only: this runs on every check.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from core.errors import AuthnError
from signatures.classify.verify import UNKNOWN  # a bare (not per-alternative) LLR is against the background

__all__ = ["DEFAULT_FALSE_ACCEPT", "DEFAULT_FALSE_REJECT", "DWELL_CAP_NATS", "DWELL_CORRELATION",
           "MAX_DWELLS_TO_DECIDE", "Sprt", "alternative_sums", "observations"]
#: Target rate of accepting an impostor's track (alpha): Wald's accept bound log((1-b)/a) = 6.9 nats.
DEFAULT_FALSE_ACCEPT = 1e-3
#: Target rate of rejecting a genuine track (beta): Wald's reject bound log(b/(1-a)) = -4.6 nats.
DEFAULT_FALSE_REJECT = 1e-2
#: Correlation of the verification LLRs of dwells of one airframe (intra-class correlation).
#: Measured at most 0.07 on the training simulator (paper preset, SNR 0-20 dB, genuine and
#: type-spoof tracks); on the held-out signal model 0.07-0.09 for type spoofs and 0.37-0.50 for
#: genuine tracks, whose one airframe, read wrongly, repeats (docs/tracks.md, "Dependence";
#: `authn bench --track [--world heldout]`). 0.2 is a margin over the impostors' dependence, which
#: is what the false-accept target needs; genuine dependence above it costs false rejects only.
#: Not fitted to any decision rate.
DWELL_CORRELATION = 0.2
#: Most a single dwell adds to (or takes from) the track's LLR, nats: below the accept bound, so
#: no track is accepted on one dwell alone.
DWELL_CAP_NATS = 4.0
#: `Sprt.dwells_to_decide` looks this far ahead.
MAX_DWELLS_TO_DECIDE = 1000
_CN = 100.0  # centinats: Cedar compares integers


@dataclass(frozen=True)
class Sprt:
    """Wald's test with the dependence discount: bounds from the target error rates."""

    false_accept: float = DEFAULT_FALSE_ACCEPT
    false_reject: float = DEFAULT_FALSE_REJECT
    correlation: float = DWELL_CORRELATION
    cap_nats: float = DWELL_CAP_NATS

    def __post_init__(self) -> None:
        for name, v in (("false accept rate", self.false_accept), ("false reject rate", self.false_reject)):
            if not 0.0 < v < 0.5:  # NaN too
                raise AuthnError(f"{name}: {v!r} is not in (0, 0.5)")
        if not 0.0 <= self.correlation < 1.0:
            raise AuthnError(f"dwell correlation: {self.correlation!r} is not in [0, 1)")
        if not 0.0 < self.cap_nats <= 100.0:
            raise AuthnError(f"dwell cap: {self.cap_nats!r} nats is not in (0, 100]")

    @property
    def accept_nats(self) -> float:
        return math.log((1.0 - self.false_reject) / self.false_accept)

    @property
    def reject_nats(self) -> float:
        return math.log(self.false_reject / (1.0 - self.false_accept))

    def increment(self, llr: float, physics: bool = True) -> float:
        """One dwell's contribution: its LLR capped at +-`cap_nats`; without a physics term (the
        classifier alone) only what counts against the claim (the default policy's
        the classifier never carries a claim). An LLR that is not a number
        counts fully against the claim (fail closed: `min` and `max` would make it +cap)."""
        capped = -self.cap_nats if math.isnan(llr) else max(-self.cap_nats, min(self.cap_nats, llr))
        return capped if physics else min(0.0, capped)

    def increments(self, against: Mapping[str, float], physics: bool = True) -> dict[str, float]:
        """One dwell's increments against each alternative (`Verification.against`: alternative ->
        LLR of the claim against it), each as `increment` makes it."""
        return {k: self.increment(v, physics) for k, v in against.items()}

    def track_llr(self, increments: Sequence[float | Mapping[str, float]]) -> float:
        """n_eff times the mean increment: sum / (1 + (n - 1) rho) (module docstring). Increments
        given per alternative (`increments`) are summed per alternative over the dwells and the
        least sum counts: the claim must win against every alternative, each on all its dwells.
        A dwell that lacks an alternative counts its least increment for it."""
        sums = alternative_sums(increments)
        return min(sums.values()) / self._discount(observations(increments)) if sums else 0.0

    def refute_llr(self, increments: Sequence[float | Mapping[str, float]]) -> float:
        """What refutes the claim: its LLR against the alternatives together, an equal-prior mixture
        -log mean_a exp(-sum_a), discounted as `track_llr`. Wald's false-reject rate holds for this
        one likelihood ratio; refuting on the least sum instead would refute a genuine claim whenever
        any one alternative's sum strayed to the bound (up to K times beta). At least `track_llr`,
        at most log K above it; equal to it for one alternative."""
        sums = list(alternative_sums(increments).values())
        if not sums:
            return 0.0
        top = min(sums)
        mixture = top - math.log(sum(math.exp(top - s) for s in sums) / len(sums))
        return mixture / self._discount(observations(increments))

    def _discount(self, n: int) -> float:
        return 1.0 + (max(n, 1) - 1) * self.correlation

    def bounds_cn(self) -> tuple[int, int]:
        """(accept, reject) bounds in centinats as the policy reads them: rounded away from 0."""
        return math.ceil(self.accept_nats * _CN), math.floor(self.reject_nats * _CN)

    def record(self, increments: Sequence[float | Mapping[str, float]]) -> dict[str, int]:
        """The `track` record of the Cedar context (docs/policies.md), in centinats: the LLR that
        accepts (`track_llr`: against each alternative) and the one that refutes (`refute_llr`:
        against them together) over the dwells that verified anything, and the bounds; a single check
        is a track of one dwell."""
        accept_cn, reject_cn = self.bounds_cn()
        return {"llr_cn": _cn(self.track_llr(increments)), "refute_llr_cn": _cn(self.refute_llr(increments)),
                "accept_cn": accept_cn, "reject_cn": reject_cn, "dwells": len(increments)}

    def dwells_to_decide(self, separation_nats: float, llr_nats: float = 0.0, used: int = 0) -> int | None:
        """About how many more dwells, each adding `separation_nats` (the expected per-dwell LLR,
        capped), take a track at `llr_nats` after `used` dwells to a bound; None where they never
        do (the discount makes n_eff level off at 1 / rho, so a separation below bound * rho never
        reaches it), or not within `MAX_DWELLS_TO_DECIDE`. Closed form of the discounted sum
        (sum_so_far + k step) / (1 + (used + k - 1) rho) reaching the bound."""
        if math.isnan(separation_nats) or math.isnan(llr_nats) or not separation_nats:
            return None
        step = max(-self.cap_nats, min(self.cap_nats, separation_nats))
        bound = self.accept_nats if step > 0 else self.reject_nats
        base = 1.0 + (used - 1) * self.correlation  # the discount's denominator less k rho
        total = llr_nats * (1.0 + max(used - 1, 0) * self.correlation)  # the undiscounted sum so far
        gain = step - bound * self.correlation  # what each dwell moves the sum past the bound's growth
        if gain * (1 if step > 0 else -1) <= 0:
            return None
        k = max(1, math.ceil((bound * base - total) / gain - 1e-12))
        return k if k <= MAX_DWELLS_TO_DECIDE else None

    def walk(self, dwells: Sequence[tuple[float | Mapping[str, float], bool]]) -> tuple[str, int]:
        """The sequential test alone over dwells given as (LLR, or LLR per alternative; physics term
        present), in order: ("accept" | "reject" | "inconclusive", dwells used). What the default
        policy's radar rules decide on the request `decide_track` builds (the track LLR in
        centinats against the same rounded bounds), with no other forbid: the site enrolment's
        track-level pairwise errors (`signatures.train.enrol`, cross-validated dwell LLRs) are computed
        with it."""
        accept_cn, reject_cn = self.bounds_cn()
        increments: list[Mapping[str, float]] = []
        for llr, physics in dwells:
            increments.append(self.increments(llr if isinstance(llr, Mapping) else {UNKNOWN: llr}, physics))
            rec = self.record(increments)
            if rec["llr_cn"] >= accept_cn:
                return "accept", len(increments)
            if rec["refute_llr_cn"] <= reject_cn:
                return "reject", len(increments)
        return "inconclusive", len(increments)

    def to_json(self) -> dict[str, float]:
        return {"false_accept": self.false_accept, "false_reject": self.false_reject,
                "accept_nats": round(self.accept_nats, 4), "reject_nats": round(self.reject_nats, 4),
                "dwell_correlation": self.correlation, "dwell_cap_nats": self.cap_nats}


def observations(increments: Sequence[float | Mapping[str, float]]) -> int:
    """How many of the dwells' increments observe the claim: those that move some alternative's sum.
    A dwell whose physics term abstained and whose classifier favoured the claim adds 0 to every sum
    (the classifier never carries a claim): it says nothing, and counted in the discount it would
    only dilute what the other dwells measured."""
    return sum(1 for d in increments if any(v != 0.0 for v in (d.values() if isinstance(d, Mapping) else (d,))))


def alternative_sums(increments: Sequence[float | Mapping[str, float]]) -> dict[str, float]:
    """Each alternative's sum of increments over the dwells (a bare LLR is the background's; a dwell
    that lacks an alternative counts its least increment for it), by alternative."""
    per = [d if isinstance(d, Mapping) else {UNKNOWN: float(d)} for d in increments]
    return {k: sum(d.get(k, min(d.values())) for d in per) for k in sorted({k for d in per for k in d})}


def _cn(nats: float) -> int:
    """Nats as the policy's centinats (Cedar compares integers), clamped inside its range."""
    return int(round(max(-1e6, min(1e6, nats * _CN))))
