"""A track's flash rate: what its dwells' own flash trains agree on, and each dwell read at it.

One airframe's rotors turn at nearly one rate over a track, while a dwell at low SNR may show its
flash train under the detection bar of a search over every rate (`flash_spectrum.SPECTRAL_DETECT_SCORE`),
or read a stronger line at a multiple. Once the track's own trains agree on a rate
(`consensus_rate`), a dwell whose own read shows no train there is read within
`flash_spectrum.TRACK_RATE_WINDOW` of it (`read_at_track_rate`), where a far lower bar holds
(`flash_spectrum.TRACK_READ_SCORE`: one window, not the whole range). The rate read there is
the airframe's own, whatever the claim: it repeats what the track's trains measured and says
nothing for or against any model the verification does not already say from them; it lets a weak
dwell count as a strong one of the same airframe would (docs/tracks.md, "A track's rate").
Nothing here is read from the claim. numpy and math only: this runs on every track check.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from signatures.dsp.flash_spectrum import TRACK_RATE_WINDOW

__all__ = ["MIN_AGREEING", "consensus_rate", "read_at_track_rate"]

#: Dwells whose trains must agree on a rate before the track has one (and at least half of the
#: dwells with a train): one train read at a wrong rate (1 % of held-out dwells) sets no rate.
MIN_AGREEING = 2


def consensus_rate(rates: Sequence[float]) -> float | None:
    """The rate the dwells' own flash trains (`rates`, Hz, one per dwell with a train) agree on: the
    median of the largest group within TRACK_RATE_WINDOW of one of them, where it holds at least
    `MIN_AGREEING` and at least half of them; None otherwise. Rates that are no rate are left out."""
    good = sorted(r for r in rates if math.isfinite(r) and r > 0.0)
    best: list[float] = []
    for centre in good:
        group = [r for r in good if abs(r - centre) <= TRACK_RATE_WINDOW * centre]
        if len(group) > len(best):
            best = group
    if len(best) < MIN_AGREEING or 2 * len(best) < len(good):
        return None
    return float(np.median(best))


def read_at_track_rate(estimates: Mapping[str, float], curve: Any, track_rate_hz: float) -> dict[str, float]:
    """What changes in a dwell's estimates (`FeatureResult` features and physics) read at the track's
    rate: nothing where its own read is a train within TRACK_RATE_WINDOW of it or its curve
    (`flash_spectrum.FlashCurve`) shows no train there; else the rate, std and score read there,
    marked `flash_track_rate_hz` (the verification takes the score as read: `read_near` held it to
    its bar), the rotors left uncounted (they were counted at the dwell's own rate)."""
    from signatures.classify.verify import min_flash_score

    own, score = float(estimates.get("flash_rate_hz", 0.0)), float(estimates.get("flash_score", 0.0))
    if score >= min_flash_score(estimates) and abs(own - track_rate_hz) <= TRACK_RATE_WINDOW * track_rate_hz:
        return {}
    read = curve.read_near(track_rate_hz)
    if read is None:
        return {}
    rate, std, near_score = read
    return {"flash_rate_hz": rate, "flash_rate_std_hz": std, "flash_score": near_score,
            "flash_track_rate_hz": float(track_rate_hz), "rotors_seen": 0.0, "rotors_seen_std": 0.0}
