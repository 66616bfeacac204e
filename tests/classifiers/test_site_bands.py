"""A site's rate modes (`signatures.train.site_bands`): each mode is where the next flight's rate
falls, not the range of the flights enrolled."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from signatures.classify.verify import RATE_BAND
from signatures.train.site_bands import BAND_PRIOR_WEIGHT, MODE_GAP, rate_modes, uniform_support

logs_ = st.lists(st.floats(-2.0, 2.0, allow_nan=False), min_size=2, max_size=40)


@given(logs_, st.floats(-3.0, 3.0, allow_nan=False))
def test_the_support_holds_every_sample_and_moves_with_a_rate_scale(logs: list[float], shift: float) -> None:
    """It contains what was enrolled; a radar reading every rate k times higher (a shift of log k)
    moves it by log k."""
    lo, hi = uniform_support(logs)
    assert lo <= min(logs) and max(logs) <= hi
    lo2, hi2 = uniform_support([x + shift for x in logs])
    assert math.isclose(lo2, lo + shift, abs_tol=1e-9) and math.isclose(hi2, hi + shift, abs_tol=1e-9)


def test_the_support_covers_the_next_flight_where_the_enrolled_range_does_not() -> None:
    """Flights' rates uniform over a regime: on average the support is the regime's width, and it
    holds 86 %, 93 % and 96 % of it from 5, 10 and 20 enrolled flights; the enrolled range alone
    holds (n - 1) / (n + 1): 67 %, 82 % and 90 %."""
    rng = np.random.default_rng(0)
    for n, holds in ((5, 0.85), (10, 0.92), (20, 0.955)):
        samples = rng.uniform(0.0, 1.0, size=(4000, n))
        ends = np.array([uniform_support(list(s)) for s in samples])
        covered = np.clip(ends[:, 1], 0, 1) - np.clip(ends[:, 0], 0, 1)
        assert abs(float(np.mean(ends[:, 1] - ends[:, 0])) - 1.0) < 0.02
        assert float(np.mean(covered)) > holds
        enrolled_range = float(np.mean(samples.max(axis=1) - samples.min(axis=1)))
        assert abs(enrolled_range - (n - 1) / (n + 1)) < 0.02 and enrolled_range < float(np.mean(covered)) - 0.05


def test_an_airframe_that_hovers_and_idles_has_two_modes_beside_the_prior() -> None:
    """Idle flashes 2-3x below hover: two site modes and the prior, weights by recordings; a mode
    holds its own flights' rates and one idle flight outside their range by less than the pad."""
    idle = [math.log(x) for x in (0.40, 0.41, 0.415, 0.42, 0.425, 0.43, 0.44)]
    hover = [math.log(x) for x in (0.92, 0.95, 1.0, 1.03, 1.06, 1.1)]
    modes = rate_modes(idle + hover, RATE_BAND)
    assert len(modes) == 3 and modes[0][:2] == RATE_BAND
    total = len(idle) + len(hover) + BAND_PRIOR_WEIGHT
    assert [round(m[2] * total) for m in modes] == [BAND_PRIOR_WEIGHT, len(idle), len(hover)]
    (ilo, ihi, _), (hlo, hhi, _) = modes[1], modes[2]
    assert ilo < 0.40 and 0.44 < ihi < math.exp(idle[0] + MODE_GAP) and hlo < 0.92 and hhi > 1.1
    assert ilo < 0.395  # a flight idling 1.25 % under the slowest enrolled one is inside its mode
