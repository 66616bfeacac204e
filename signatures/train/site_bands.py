"""A site's physics bands: each enrolled model's flash-rate modes, rotors-seen and blade-ratio bands
re-estimated from its own recordings, today's `signatures.classify.verify` bands the prior (an
airframe that hovers and idles flashes at two rates: the rate band is a mixture of modes)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from signatures.profiles import UavProfile
from signatures.train.site_samples import MIN_RECORDINGS, SiteSample

#: Site physics bands (`site_bands`): the prior's weight in recordings, and the narrowest band (log).
BAND_PRIOR_WEIGHT = 10
BAND_MIN_LOG_WIDTH = math.log(1.06)


#: Site rates further apart than this (log) are two modes (`rate_modes`): 25 %, over twice the +-10 %
#: a rotor's rate wanders in one regime (hover 143-179 Hz), under the 2-3x between idling and hover.
MODE_GAP = math.log(1.25)


def shrunk_band(logs: list[float], prior: tuple[float, float]) -> tuple[float, float]:
    """A band (ratio lo, hi) from site log-ratios and the prior band: the uniform whose 10th and 90th
    percentiles are the site's (edges 1/8 of that span beyond them), each edge shrunk to the prior's
    in log space with `BAND_PRIOR_WEIGHT` pseudo-recordings; at least `BAND_MIN_LOG_WIDTH` wide.
    Percentiles, not `uniform_support`'s extremes: per-dwell rotor counts and blade ratios have
    outliers that no mode split sets aside, as `rate_modes` does for rates."""
    lo_p, hi_p = math.log(prior[0]), math.log(prior[1])
    if len(logs) < MIN_RECORDINGS:
        return prior
    q10, q90 = (float(v) for v in np.percentile(logs, [10, 90]))
    span = q90 - q10
    n, w = len(logs), BAND_PRIOR_WEIGHT
    lo = (w * lo_p + n * (q10 - span / 8)) / (w + n)
    hi = (w * hi_p + n * (q90 + span / 8)) / (w + n)
    if hi - lo < BAND_MIN_LOG_WIDTH:
        mid = (hi + lo) / 2
        lo, hi = mid - BAND_MIN_LOG_WIDTH / 2, mid + BAND_MIN_LOG_WIDTH / 2
    return math.exp(lo), math.exp(hi)


def uniform_support(logs: Sequence[float]) -> tuple[float, float]:
    """Where the next flight's value falls, from n >= 2 flights' values: the ends of the uniform
    they are a sample of, by the unbiased estimate from the extremes (min - span / (n - 1),
    max + span / (n - 1)). The sample's own range covers a new draw with probability
    (n - 1) / (n + 1) only (82 % at n = 10); its 10th and 90th percentiles, widened by an eighth
    of their span, cover about as much at that n."""
    lo, hi = float(min(logs)), float(max(logs))
    pad = (hi - lo) / (len(logs) - 1)
    return lo - pad, hi + pad


def rate_modes(logs: list[float], prior: tuple[float, float]) -> list[tuple[float, float, float]]:
    """The site's rates as a mixture (ratio lo, hi, weight): the prior band weighing
    `BAND_PRIOR_WEIGHT` pseudo-recordings, and each mode of the site's log-ratios (neighbours at
    most `MODE_GAP` apart; a mode of fewer than `MIN_RECORDINGS` joins its nearest) as a band of
    its own (`uniform_support`; no shrinkage: the prior is its own component) weighing its recordings.
    An airframe that hovers and idles flashes at two rates 2-3x apart: one band over both would
    spread its density over the gap between them. [] below `MIN_RECORDINGS`."""
    if len(logs) < MIN_RECORDINGS:
        return []
    xs = sorted(logs)
    groups: list[list[float]] = [[xs[0]]]
    for x in xs[1:]:
        if x - groups[-1][-1] <= MODE_GAP:
            groups[-1].append(x)
        else:
            groups.append([x])
    while len(groups) > 1 and min(len(g) for g in groups) < MIN_RECORDINGS:
        i = min(range(len(groups)), key=lambda k: len(groups[k]))
        left = groups[i][0] - groups[i - 1][-1] if i > 0 else math.inf
        right = groups[i + 1][0] - groups[i][-1] if i + 1 < len(groups) else math.inf
        j = i - 1 if left <= right else i + 1
        a, b = min(i, j), max(i, j)
        groups[a:b + 1] = [groups[a] + groups[b]]
    total = len(xs) + BAND_PRIOR_WEIGHT
    out = [(prior[0], prior[1], BAND_PRIOR_WEIGHT / total)]
    for g in groups:
        lo, hi = uniform_support(g)
        if hi - lo < BAND_MIN_LOG_WIDTH:
            mid = (hi + lo) / 2
            lo, hi = mid - BAND_MIN_LOG_WIDTH / 2, mid + BAND_MIN_LOG_WIDTH / 2
        out.append((math.exp(lo), math.exp(hi), len(g) / total))
    return out


def site_bands(samples: Sequence[SiteSample], profiles: dict[str, UavProfile],
               max_tip_mps: float | None = None) -> dict[str, dict[str, Any]]:
    """Each model's physics bands re-estimated from its site recordings (`shrunk_band`, today's
    `signatures.classify.verify` bands the prior): the flash rate over the nominal (estimates the rate
    term would use) as a mixture of the prior and the site's modes (`rate_modes`; `rate` their
    envelope, what the open set's rate test takes), the rotors seen over the rotor count (counts
    the rotor term would use) and the blade ratio, tip speed over flash rate over the claim's
    (where the blade term runs: tips unaliased, the claim's tips below `max_tip_mps`)."""
    from signatures.classify.verify import (BLADE_BAND, MAX_REL_STD, MIN_FLASH_GROUPS, RATE_BAND, ROTOR_BAND,
                                            min_flash_score, rotors_are_lower_bound)

    out: dict[str, dict[str, Any]] = {}
    for m in sorted({s.model for s in samples}):
        prof = profiles[m]
        tips_fit = max_tip_mps is None or prof.tip_speed_mps * RATE_BAND[1] < max_tip_mps
        rate: list[float] = []
        rot: list[float] = []
        blade: list[float] = []
        for s in samples:
            if s.model != m or not s.detected:
                continue
            f, sd = s.physics.get("flash_rate_hz", 0.0), s.physics.get("flash_rate_std_hz", 0.0)
            if f > 0 and s.physics.get("flash_score", 0.0) >= min_flash_score(s.physics) and sd / f <= MAX_REL_STD:
                rate.append(math.log(f) - math.log(prof.blade_flash_rate_hz))
                tip = s.physics.get("tip_speed_mps", 0.0)
                if tip > 0 and tips_fit and s.physics.get("tip_aliased", 0.0) < 0.5:
                    y = math.log(tip) - math.log(f) - math.log(prof.tip_speed_mps / prof.blade_flash_rate_hz)
                    if y >= math.log(BLADE_BAND[0]):
                        blade.append(y)
            seen, ssd = s.physics.get("rotors_seen", 0.0), s.physics.get("rotors_seen_std", 0.0)
            visible = rotors_are_lower_bound(s.physics)  # rotors visible, a lower bound: no band to fit
            if seen > 0 and ssd > 0 and ssd / seen <= 1.0 / math.sqrt(MIN_FLASH_GROUPS) + 1e-9 and not visible:
                rot.append(math.log(seen) - math.log(prof.rotors))
        modes = rate_modes(rate, RATE_BAND)
        band = (min(b[0] for b in modes), max(b[1] for b in modes)) if modes else shrunk_band(rate, RATE_BAND)
        out[m] = {"rate": [round(v, 6) for v in band], "rate_modes": [[round(v, 6) for v in b] for b in modes],
                  "rotors": [round(v, 6) for v in shrunk_band(rot, ROTOR_BAND)],
                  "blade": [round(v, 6) for v in shrunk_band(blade, BLADE_BAND)],
                  "n_rate": len(rate), "n_rotors": len(rot), "n_blade": len(blade)}
    return out

