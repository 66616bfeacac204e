"""1:1 verification: is this return consistent with the *claimed* airframe? (docs/classifiers.md "Verification")

Classification answers "which enrolled type is it?"; authentication needs "is it the type the
claim names?". `verify` scores one return against one claimed `UavProfile` as a log-likelihood
ratio (natural log) of "the claimed airframe" against "some other multirotor", summed over
independent terms:

* **physics**, from two ratios:
  - rate: the blade-flash rate over the claim's nominal one, r = f / F. A flown rotor turns at
    `RATE_BAND` of its nominal rate (hover against climb, payload, battery), so under the claim
    log r is uniform over that band blurred by the estimator's error; under the alternative
    log r is uniform over `ALT_LOG_SPAN`.
  - blade (unaliased tips only): tip speed over flash rate is 2 pi L / N times the LOS
    projection, whatever the rotor rate. Over the claim's value it lies in `BLADE_BAND`: never
    above 1 (+5 %), while projection and noise only shrink it, so the test is an upper bound
    (tips too fast for the claimed blades).
  - rotors: distinct flashes per flash period (`flash_period.rotors_seen`, rate-invariant) over
    the claim's rotor count lies in `ROTOR_BAND` (rotors flashing together count once, weak
    flashes are missed), blurred by the count's own 1/sqrt(flashes) and `ROTOR_REL_FLOOR`;
    under the alternative its log is uniform over `ROTOR_ALT_LOG_SPAN`. Left out below
    `MIN_FLASH_GROUPS` flashes. A long dwell's count is of the rotors *visible* above the noise
    (`rotors_lower_bound`, `signatures.dsp.rotor_lines`): a lower bound, so it only vetoes: the
    factor is the chance that the claim's count (its rotors, `VISIBLE_SLACK` lines over it at
    most) reaches what was seen, blurred as above, never more than 1 (fewer rotors visible than
    claimed is no evidence).
  The estimator's known failure, a whole-period slip of the flash rate, keeps `SLIP_WEIGHT` of
  the claim's mass at the `SLIPS` multiples, every ratio evaluated under the same slip.
* **classifier**: the bundle's calibrated probability of the claimed class as log-odds against
  its prior 1/K, clipped to +-`CLASSIFIER_CLIP` (a classifier fitted to one simulator is not
  trusted further than that). Absent when the claim is not one of the bundle's classes: a new
  profile registered from its physical parameters is verified by the physical terms alone. Where
  the open-set test calls the return `unknown` (it fits no enrolled profile), the closed-set
  classifier's support for the claim is no evidence, so the term is capped at 0: it may count
  against the claim, never for it.

A site bundle (`authn models enrol`) may carry `Bands` per enrolled model: the rate, rotor and
blade-ratio bands re-estimated from the site's own recordings with the bands above as the prior
(`signatures.train.enrol`); without them (every other bundle) the bands above apply unchanged.

**A group of radar-confusable models** (`also`): where a site's enrolment card says radar cannot
tell the claimed model from other models registered there, and a valid DRIP signature vouches for
the exact identity (the check decides when), the return is verified against the group: the physics
term is the log of the mean of the members' likelihood ratios (the claim is one of them, equally
likely), the classifier's term the summed probability of the members against their share of the
prior (absent where the group holds every class the bundle knows: it then tells the group from
nothing). Radar vouches for what it can tell; the signature for the rest.

A site bundle may also carry a score calibration (`signatures.classify.calibration`, fitted on its
enrolment's cross-validated terms, applied with `authn models enrol --calibrate`): the LLR is then
the calibrated terms' sum; where the physics term abstains it stays absent all the same.

**Against the alternatives that matter.** The terms above score the claim against a background (some
other multirotor): a rate two registered models share supports either. So the claim is also scored
against each other model registered at the site (`alternatives`): the physics terms' difference (both
against the same background: their likelihood ratio, ~0 where the bands overlap) plus the classifier's
pairwise log-odds (clipped, capped at 0 where the open set calls the return unknown; absent for a model
the bundle does not know, which its physics bands alone tell apart). The LLR is the least of these and
the background's: the claim must win against every alternative, the closest one named
(`Verification.closest`). A group's members are not alternatives to it.

A term abstains (is left out) when its estimate is unreliable; the physics term is floored at
`TERM_FLOOR`. The Cedar policy thresholds the
sum. numpy and math only: this runs on the inference path.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from signatures.profiles import NON_UAV_CLASSES, UavProfile

__all__ = ["ALT_LOG_SPAN", "BLADE_BAND", "CLASSIFIER_CLIP", "PHYSICS_READS", "RATE_BAND", "ROTOR_BAND", "UNKNOWN",
           "Bands", "Verification",
           "bands_from", "min_flash_score", "rate_from_track", "rotors_are_lower_bound", "verify"]

#: Flown rotor rate over the profile's nominal rate (hover to climb, payload, battery sag).
#: every estimate the physics term reads (`authn features show` prints these as the physics the
#: decision uses); the rotor count it reads is `rotors_seen`, never the feature `rotor_count`
PHYSICS_READS = ("flash_rate_hz", "flash_rate_std_hz", "flash_score", "tip_speed_mps", "tip_speed_std_mps",
                 "tip_aliased", "rotors_seen", "rotors_seen_std", "rotors_lower_bound", "flash_track_rate_hz")
RATE_BAND = (0.80, 1.20)
#: Tip-speed / flash-rate over the claim's 2 pi L / N: cos(elevation) (0.45 = 63 deg) up to +5 %.
BLADE_BAND = (0.05, 1.05)
#: The alternative hypothesis: a ratio anywhere within a factor 8 either way, log-uniform.
ALT_LOG_SPAN = math.log(64.0)
#: Rotors seen over the claimed rotor count. Below 1: two of R rotors with random phases flash
#: within the 3 % group gap with probability ~0.06 per pair (4 rotors: 0.91 expected, 8: 0.79),
#: and weak flashes go unseen; above 1: a flash split wider than the gap.
ROTOR_BAND = (0.70, 1.10)
ROTOR_REL_FLOOR = 0.10
#: A visible-rotor count (a lower bound) is held against a claim from this many lines over its
#: rotors: a residue line is one (the count's std), so the veto is half-way at two over.
VISIBLE_SLACK = 2.0
#: The alternative: a multirotor with 2 to 12 rotors, log-uniform.
ROTOR_ALT_LOG_SPAN = math.log(12.0 / 2.0)
MIN_FLASH_GROUPS = 3
#: The estimator's relative accuracy floor (5 % demonstrated on known airframes; 3 % floor).
REL_FLOOR = 0.03
#: Share of the claim's mass at whole-period slips of the flash-rate estimate: half the rate
#: (unequal blades flash unequally: one flash per turn), and when the tips alias also twice or
#: three times (flashes folded onto each other).
SLIP_WEIGHT = 0.3
SLIPS = (0.5, 2.0, 3.0)
UNALIASED_SLIPS = (0.5,)
#: Below this flash score the rate estimate is noise (the open set's own threshold).
MIN_FLASH_SCORE = 1.0
#: A long dwell's rate (the envelope spectrum's, `flash_spectrum.spectral_flash_rate`) is a flash
#: train from the score at which it is a detection (`flash_spectrum.SPECTRAL_DETECT_SCORE`: 5x the highest that
#: noise and clutter alone reach): wind-blown clutter lowers the score of a rate it leaves right
#: (one knob at a time on the randomised world's CW hover, 20 scenes: score >= 1 in 19 -> 10, the rate
#: right in 20 -> 20), and the period search's bar of 1 then left right rates unused.
MIN_SPECTRAL_SCORE = 0.4
CLASSIFIER_CLIP = 3.0
#: A class probability sum may exceed 1 by this much (float rounding of a softmax) and still be one.
PROBABILITY_SLACK = 1e-6
#: An estimate whose stated std exceeds this share of its value abstains.
MAX_REL_STD = 1.0
TERM_FLOOR = -8.0
#: The alternative every claim is scored against: an airframe no registered profile describes.
UNKNOWN = "unknown"
#: A reported ratio's log is capped here (e**700 is still a finite float).
MAX_REPORTED_LOG = 700.0


@dataclass(frozen=True)
class Bands:
    """One claimed model's physics bands: flown rate over nominal (`RATE_BAND`), rotors seen
    over rotors (`ROTOR_BAND`) and the blade ratio (`BLADE_BAND`). The defaults are today's fixed
    bands."""

    rate: tuple[float, float] = RATE_BAND
    rotors: tuple[float, float] = ROTOR_BAND
    blade: tuple[float, float] = BLADE_BAND
    #: the rate as a mixture of bands (lo, hi, weight) where a site measured modes; (): `rate` alone
    rate_modes: tuple[tuple[float, float, float], ...] = ()


DEFAULT_BANDS = Bands()


def bands_from(card_bands: Mapping[str, Any] | None, model: str) -> Bands | None:
    """`model`'s bands from a site card's `enrolment.bands` (slug -> {"rate": [lo, hi], "rotors":
    [lo, hi], "blade": [lo, hi] (optional: `BLADE_BAND`), "rate_modes": [[lo, hi, weight], ...]
    (optional)}); None (today's bands) where the card has none for it."""
    b = (card_bands or {}).get(model)
    if not b:
        return None
    blade = b.get("blade") or BLADE_BAND
    modes = tuple((float(lo), float(hi), float(w)) for lo, hi, w in b.get("rate_modes") or ())
    return Bands(rate=(float(b["rate"][0]), float(b["rate"][1])), rotors=(float(b["rotors"][0]), float(b["rotors"][1])),
                 blade=(float(blade[0]), float(blade[1])), rate_modes=modes)


@dataclass(frozen=True)
class Verification:
    """The verification of one return against one claimed airframe."""

    llr: float  # nats, the least of `against`: > 0 favours the claim over every alternative
    terms: dict[str, float] = field(default_factory=dict)  # the terms that did not abstain
    #: what the physics term compared: measured against claimed, for the operator
    compared: dict[str, dict[str, float]] = field(default_factory=dict)
    #: the terms before clipping and calibration (`signatures.classify.calibration.RawTerms`)
    raw: Any = None
    #: with a site calibration: the uncalibrated terms (what verify gives without it)
    uncalibrated: dict[str, float] = field(default_factory=dict)
    #: verified against a group of radar-confusable models: the group's slugs, the claim's first
    verified_as: tuple[str, ...] = ()
    #: the claim's LLR against each alternative: `UNKNOWN` (the background: some other multirotor)
    #: and each other model registered at the site; `llr` is the least of them
    against: dict[str, float] = field(default_factory=dict)

    @property
    def closest(self) -> str | None:
        """The alternative the claim is least separated from (None: nothing was verified)."""
        if not (self.against and self.terms):
            return None
        return min(self.against, key=lambda k: -math.inf if math.isnan(self.against[k]) else self.against[k])

    @property
    def physics_abstained(self) -> bool:
        """No physics term: the rotors gave no usable rate estimate. The classifier's term alone
        is then all the score holds, and the policy does not let it carry a claim
        (its increment counts only against the claim: `authn.sprt.Sprt.increment`)."""
        return "physics" not in self.terms

    def to_json(self) -> dict[str, object]:
        doc: dict[str, object] = {"llr": round(self.llr, 4), "terms": {k: round(v, 4) for k, v in self.terms.items()}}
        if self.compared:
            doc["compared"] = {k: {n: round(v, 3) for n, v in d.items()} for k, d in self.compared.items()}
        if self.uncalibrated:
            doc["uncalibrated"] = {k: round(v, 4) for k, v in self.uncalibrated.items()}
        if self.verified_as:
            doc["verified_as"] = list(self.verified_as)
        if len(self.against) > 1:
            doc["against"] = {k: round(v, 4) for k, v in self.against.items()}
            doc["closest"] = self.closest
        return doc


def rotors_are_lower_bound(estimates: Mapping[str, float]) -> bool:
    """Whether `estimates` (features, or a `FeatureResult.physics`) count the rotors *visible* above
    the noise (a long dwell's `rotors_lower_bound`), which only vetoes, rather than those seen."""
    return float(estimates.get("rotors_lower_bound", 0.0)) >= 0.5


def rate_from_track(estimates: Mapping[str, float]) -> bool:
    """Whether `estimates`' rate was read at a track's rate (`signatures.classify.track_rate`)."""
    return float(estimates.get("flash_track_rate_hz", 0.0)) > 0.0


def min_flash_score(estimates: Mapping[str, float]) -> float:
    """The flash score from which `estimates`' rate is read: a long dwell's (its rotors counted as a
    lower bound: the mark the long-dwell path sets) or the period search's; 0 for a rate read at a
    track's rate, whose reader held it to its own bar (`flash_spectrum.TRACK_READ_SCORE`)."""
    if rate_from_track(estimates):
        return 0.0
    return MIN_SPECTRAL_SCORE if rotors_are_lower_bound(estimates) else MIN_FLASH_SCORE


def _phi(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def _band_density(x: float, lo: float, hi: float, sigma: float) -> float:
    """Density at x of uniform[lo, hi] convolved with N(0, sigma^2)."""
    return (_phi((hi - x) / sigma) - _phi((lo - x) / sigma)) / (hi - lo)


def _rate_density(x: float, bands: Bands, sigma: float) -> float:
    """Density of log(rate / nominal) at x: the rate band, or the site's mixture of bands."""
    if bands.rate_modes:
        return sum(w * _band_density(x, math.log(lo), math.log(hi), sigma) for lo, hi, w in bands.rate_modes)
    return _band_density(x, math.log(bands.rate[0]), math.log(bands.rate[1]), sigma)


def _physics(features: Mapping[str, float], claimed: UavProfile, max_tip_mps: float | None,
             bands: Bands = DEFAULT_BANDS) -> tuple[float, dict[str, dict[str, float]]] | None:
    """(log p(rate, blade, rotors | claim) - log p(rate, blade, rotors | other), what was compared),
    or None when the rate estimate is unreliable. Slip hypotheses m scale the measured rate
    (f = m r F) and hence the blade ratio (tip / f carries 1/m) and the rotors seen (1/m): all are
    evaluated under the same m."""
    f = float(features.get("flash_rate_hz", 0.0))
    F = claimed.blade_flash_rate_hz
    if not (f > 0 and F > 0 and float(features.get("flash_score", 0.0)) >= min_flash_score(features)):
        return None
    f_rel = float(features.get("flash_rate_std_hz", 0.0)) / f
    if not 0.0 <= f_rel <= MAX_REL_STD:  # an estimate less certain than itself says nothing (NaN, < 0 too)
        return None
    x = math.log(f) - math.log(F)  # logs apart: f / F underflows for a subnormal f
    sigma_rate = math.hypot(f_rel, REL_FLOOR)
    tip = float(features.get("tip_speed_mps", 0.0))
    tips_fit = max_tip_mps is None or claimed.tip_speed_mps * RATE_BAND[1] < max_tip_mps
    blade = None
    if tip > 0 and tips_fit and float(features.get("tip_aliased", 0.0)) < 0.5:
        tip_rel = float(features.get("tip_speed_std_mps", 0.0)) / tip
        y = math.log(tip) - math.log(f) - math.log(claimed.tip_speed_mps / F)  # over 2 pi L / N
        if 0.0 <= tip_rel <= MAX_REL_STD and y >= math.log(BLADE_BAND[0]):  # below: the tips were not seen
            sigma = math.sqrt(tip_rel ** 2 + f_rel ** 2 + REL_FLOOR ** 2)
            blade = (y, math.log(bands.blade[0]), math.log(bands.blade[1]), sigma)
    veto = rotors_are_lower_bound(features)
    rotors = _rotors(features, claimed, (bands.rotors[0], (claimed.rotors + VISIBLE_SLACK) / claimed.rotors) if veto
                     else bands.rotors)
    compared = {"flash_rate_hz": {"measured": f, "claimed": F}}
    if rate_from_track(features):  # read near the rate the track's own trains agree on
        compared["flash_rate_hz"]["track_rate"] = float(features["flash_track_rate_hz"])
    if blade is not None:  # tip speed over flash rate, over the claim's 2 pi L / N: at most 1.05
        # capped for the report: a tip estimate against a near-zero rate can exceed a float's range
        compared["blade_ratio"] = {"measured": math.exp(min(blade[0], MAX_REPORTED_LOG)), "claimed_max": bands.blade[1]}
    if rotors is not None:
        compared["rotors"] = {"seen": float(features["rotors_seen"]), "claimed": float(claimed.rotors)}
    slips = SLIPS if float(features.get("tip_aliased", 0.0)) >= 0.5 else UNALIASED_SLIPS
    p = 0.0
    for m, w in ((1.0, 1.0 - SLIP_WEIGHT), *((m, SLIP_WEIGHT / len(slips)) for m in slips)):
        q = w * _rate_density(x - math.log(m), bands, sigma_rate)
        if blade is not None:
            y, lo, hi, sigma = blade
            q *= _band_density(y + math.log(m), lo, hi, sigma)
        if rotors is not None:  # a rate m times the true one counts the rotors 1/m times
            z, lo, hi, sigma = rotors
            q *= _phi((hi - z - math.log(m)) / sigma) if veto else _band_density(z + math.log(m), lo, hi, sigma)
        p += q
    two_sided = rotors is not None and not veto
    alt = 1.0 / ALT_LOG_SPAN ** (2 if blade is not None else 1) / (ROTOR_ALT_LOG_SPAN if two_sided else 1.0)
    return max(TERM_FLOOR, math.log(max(p, 1e-300)) - math.log(alt)), compared


def _rotors(features: Mapping[str, float], claimed: UavProfile,
            band: tuple[float, float] = ROTOR_BAND) -> tuple[float, float, float, float] | None:
    """(log of rotors seen over the claim's rotors, band, sigma), or None when too few flashes
    were seen (or none were counted: an older extraction, a quick one)."""
    seen = float(features.get("rotors_seen", 0.0))
    std = float(features.get("rotors_seen_std", 0.0))
    if not (seen > 0.0 and std > 0.0):
        return None
    rel = std / seen  # a count's relative std, 1 / sqrt(flashes counted)
    if not 0.0 <= rel <= 1.0 / math.sqrt(MIN_FLASH_GROUPS) + 1e-9:  # NaN and < 0 too
        return None
    z = math.log(seen) - math.log(claimed.rotors)
    return z, math.log(band[0]), math.log(band[1]), math.hypot(rel, ROTOR_REL_FLOOR)


def _group_physics(features: Mapping[str, float], members: Sequence[tuple[UavProfile, Bands]],
                   max_tip_mps: float | None) -> tuple[float, dict[str, dict[str, float]]] | None:
    """The physics term of "one of `members`" (the claim first): the log of the mean of their
    likelihood ratios; what was compared is the claim's. None where the claim's term abstains."""
    scored = [_physics(features, p, max_tip_mps, b) for p, b in members]
    if scored[0] is None:
        return None
    llrs = [s[0] for s in scored if s is not None]
    top = max(llrs)
    return top + math.log(sum(math.exp(x - top) for x in llrs) / len(members)), scored[0][1]


def _log_odds(probabilities: Mapping[str, float], slugs: Sequence[str]) -> float | None:
    """Log-odds of the summed probability of `slugs` against their share of a uniform prior over the
    bundle's UAV classes; None where none of them is a class, or they are every class; -inf (fail
    closed: as far against the claim as the term goes) where the sum is no probability (NaN,
    infinite, negative or over 1), which clipping would otherwise turn into support."""
    uav = [c for c in probabilities if c not in NON_UAV_CLASSES]
    inside = [s for s in slugs if s in probabilities]
    if not inside or len(inside) >= max(len(uav), 2):
        return None
    prior = len(inside) / max(len(uav), 2)
    total = sum(float(probabilities[s]) for s in inside)
    if not 0.0 <= total <= 1.0 + PROBABILITY_SLACK:
        return -math.inf
    p = min(max(total, 1e-6), 1.0 - 1e-6)
    return math.log(p / (1.0 - p)) - math.log(prior / (1.0 - prior))


def _pairwise(physics: float | None, other: tuple[float, dict] | None, probabilities: Mapping[str, float] | None,
              claim: Sequence[str], alternative: str, known: bool) -> float:
    """The claim against one registered alternative: the physics terms' difference (both scored
    against the same background, so it is their likelihood ratio: ~0 where they share a band) plus
    the classifier's pairwise log-odds, clipped at +-`CLASSIFIER_CLIP` and capped at 0 where the
    open set calls the return unknown; 0 where the classifier does not know both (a user's own
    airframe is told apart by its physics bands alone). A pairwise log-odds that is no number
    counts at its negative clip (fail closed)."""
    llr = 0.0 if physics is None or other is None else physics - other[0]
    if probabilities and alternative in probabilities and any(c in probabilities for c in claim):
        p_c = sum(float(probabilities.get(c, 0.0)) for c in claim)
        p_a = float(probabilities[alternative])
        odds = math.log(max(p_c, 1e-6)) - math.log(max(p_a, 1e-6)) if p_c >= 0 and p_a >= 0 else -math.inf
        odds = -math.inf if math.isnan(odds) else odds
        llr += max(-CLASSIFIER_CLIP, min(CLASSIFIER_CLIP if known else 0.0, odds))
    return llr


def verify(features: Mapping[str, float], claimed: UavProfile,
           probabilities: Mapping[str, float] | None = None, max_tip_mps: float | None = None,
           known: bool = True, bands: Bands | None = None, calibration: Any = None,
           also: Sequence[tuple[UavProfile, Bands | None]] = (),
           alternatives: Sequence[tuple[UavProfile, Bands | None]] = ()) -> Verification:
    """Score a return's physical estimates (feature name -> value, `signatures.features`) and
    the classifier's probabilities (class -> p, optional) against the claimed profile.

    `known`: the open-set verdict (`Prediction.known`); False caps the classifier term at 0.

    `max_tip_mps`: the fastest LOS speed the waveform measures unaliased (lambda * PRF / 4, the
    radar's `unambiguous_velocity_mps`); the blade term runs only when the claimed airframe's
    fastest tips stay below it, whatever a noisy return's own aliasing flag says.

    `bands`: the claimed model's site-estimated bands (None: `RATE_BAND`, `ROTOR_BAND`).

    `calibration`: a site's score calibration (`signatures.classify.calibration.Calibration`, fitted on its
    enrolment's cross-validated terms): the LLR against the background is then its calibrated terms'
    sum, the terms above kept as `uncalibrated`; a physics term that abstained stays absent.

    `also`: the models (with their site bands, None: the defaults) the claim is verified together
    with, as one group (module docstring); (): the claimed model alone.

    `alternatives`: the other models registered at the site (with their site bands): the LLR is the
    least of the claim's LLR against the background (`UNKNOWN`) and against each of them
    (`Verification.against`). A model of the claim's group is not an alternative."""
    from signatures.classify.calibration import RawTerms

    terms: dict[str, float] = {}
    compared: dict[str, dict[str, float]] = {}
    members = [(claimed, bands or DEFAULT_BANDS), *((p, b or DEFAULT_BANDS) for p, b in also if p.slug != claimed.slug)]
    physics = _group_physics(features, members, max_tip_mps)
    if physics is not None:
        terms["physics"], compared = physics
    slugs = [p.slug for p, _ in members]
    odds = _log_odds(probabilities, slugs) if probabilities else None
    if odds is not None:
        terms["classifier"] = max(-CLASSIFIER_CLIP, min(CLASSIFIER_CLIP if known else 0.0, odds))
    group = tuple(slugs) if len(members) > 1 else ()
    raw = RawTerms(None if physics is None else physics[0], odds, known)
    uncalibrated: dict[str, float] = {}
    if calibration is not None:
        terms, uncalibrated = calibration.terms(raw), terms
    background = sum(terms.values())
    against = {UNKNOWN: background}
    if terms:  # nothing verified: no alternative either
        p_c = None if physics is None else physics[0]
        for alt, alt_bands in alternatives:
            if alt.slug in slugs or alt.slug in against:
                continue
            other = None if p_c is None else _physics(features, alt, max_tip_mps, alt_bands or DEFAULT_BANDS)
            against[alt.slug] = _pairwise(p_c, other, probabilities, slugs, alt.slug, known)
    llr = math.nan if any(math.isnan(x) for x in against.values()) else min(against.values())  # fail closed
    return Verification(llr=llr, terms=terms, compared=compared, raw=raw, uncalibrated=uncalibrated,
                        verified_as=group, against=against)
