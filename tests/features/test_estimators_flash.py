"""Blade-flash estimator: the coherent partner checks (signatures.estimators)."""

from __future__ import annotations

import warnings

import numpy as np

from signatures import estimators as est
from signatures.radar import get_preset

PROFILE = np.array([0.5, 1.0, 0.6 - 0.2j], dtype=np.complex64)  # a hub's complex range profile


def _slow(n: int, flashes: list[tuple[int, float, float]], seed: int = 0) -> np.ndarray:
    """Unit complex noise per bin plus flashes (chirp, amplitude, phase) with PROFILE."""
    rng = np.random.default_rng(seed)
    z = ((rng.standard_normal((n, 3)) + 1j * rng.standard_normal((n, 3))) / np.sqrt(2)).astype(np.complex64)
    for t, amp, phase in flashes:
        z[t] += np.complex64(amp * np.exp(1j * phase)) * PROFILE
    return z


def test_coherent_checks_only_where_a_flash_fits_in_one_pri():
    paper, wide = get_preset("paper"), get_preset("wide")
    s = est.flash_series(_slow(paper.n_chirps, [(100, 30.0, 0.3)]), paper.config, 0.0, 1.0)
    times, _ = est.flash_events(s, s.radius)
    assert times.size >= 1 and est._coherent(s, times) is not None
    s = est.flash_series(_slow(wide.n_chirps, [(1000, 30.0, 0.3)]), wide.config, 0.0, 1.0)
    times, _ = est.flash_events(s, s.radius)
    assert times.size >= 1 and est._coherent(s, times) is None  # 6.25 us PRI: flashes span chirps


def test_coherent_hit_needs_the_same_profile_and_phase_up_to_sign():
    paper = get_preset("paper")
    # strong flash at 100; a weak same-hub flash one "period" later (sign flipped: sinc sidelobe);
    # an equally weak flash in quadrature at 400 (another rotor's random phase)
    flashes = [(100, 30.0, 0.3), (295, 4.0, 0.3 + np.pi), (400, 4.0, 0.3 + np.pi / 2)]
    s = est.flash_series(_slow(paper.n_chirps, flashes, seed=1), paper.config, 0.0, 1.0)
    times = np.array([100.0])
    coh = est._coherent(s, times)
    assert coh is not None and coh.share < 0.05
    hits = np.diff(coh.counts[0])
    assert hits[295] and not hits[400]
    weight = np.ones(1)
    found, made, chance = est._coherent_checks(coh, times, weight, np.array([195.0, 300.0]), s.energy.size)
    assert found[0] == 1.0 and found[1] == 0.0 and np.all(made == 1.0) and np.all(chance < 0.5)


def test_periodicity_of_noise_and_of_nothing_is_quiet():
    paper = get_preset("paper")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for slow in (_slow(paper.n_chirps, [], seed=2), np.zeros((paper.n_chirps, 3), np.complex64)):
            per = est.periodicity(est.flash_series(slow, paper.config, 0.0, 1.0))
            assert np.isfinite(per.flash_rate.value) and np.isfinite(per.flash_rate.std)


def test_alternate_flashes_missed_still_give_the_period():
    """One rotor of period 195 chirps whose every other flash falls between chirps (weak, below
    the energy threshold) plus a second rotor: the event vote alone gives 390 (no weak flash
    is an event in this noise draw), the coherent checks find the weak ones: 195."""
    paper = get_preset("paper")
    flashes = []
    for t0, phase in ((20, 0.4), (80, 2.0)):
        for m in range(4):
            t = t0 + 195 * m
            if t < paper.n_chirps:
                flashes.append((t, 25.0 if m % 2 == 0 else 2.2, phase + np.pi * (m % 2)))
    s = est.flash_series(_slow(paper.n_chirps, flashes, seed=4), paper.config, 0.0, 1.0)
    per = est.periodicity(s)
    period = s.rate_hz / per.flash_rate.value
    assert abs(period - 195.0) <= 2.0
