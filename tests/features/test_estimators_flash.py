"""Blade-flash estimators: matched filters (signatures.dsp.flash_series), coherent partner checks and rotors seen
(signatures.dsp.flash_period)."""

from __future__ import annotations

import math
import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.dsp import flash_period, flash_series
from signatures.dsp import rd
from signatures.radar import get_preset
from signatures.dsp.threads import one_blas_thread
from tests.features import reference_flash as ref

N_FFT = 80  # fast-time samples per chirp (the paper preset's)
HUB_BIN = 40.3  # the flashing hub's range, in bins
BINS = slice(39, 42)  # the three target bins around it


def _slow(n: int, flashes: list[tuple[int, float, float]], seed: int = 0) -> np.ndarray:
    """Hann-windowed range bins 39-41 of complex white noise (unit power per fast-time sample)
    plus flashes (chirp, amplitude, phase) of a point scatterer at HUB_BIN. Amplitude 1 puts
    the scatterer's energy at the noise level of one bin."""
    rng = np.random.default_rng(seed)
    iq = (rng.standard_normal((n, N_FFT)) + 1j * rng.standard_normal((n, N_FFT))) / math.sqrt(2.0)
    k = np.arange(N_FFT)
    # unit-mean Hann: one bin's noise power is 1.5 N, a tone of amplitude a peaks near a N
    tone = np.exp(2j * math.pi * HUB_BIN * k / N_FFT) * math.sqrt(1.5 * N_FFT) / N_FFT
    for t, amp, phase in flashes:
        iq[t] += amp * np.exp(1j * phase) * tone
    return rd.range_fft(iq.astype(np.complex64), suppress_clutter=False)[:, BINS]


def test_matched_filters_give_unit_noise_and_the_scatterer_energy():
    h = flash_series.matched_filters(3, N_FFT)
    noise = _slow(20_000, [])
    power = np.abs(noise @ h.conj()) ** 2
    assert np.allclose(power.mean(axis=0), 1.0, atol=0.05)  # unit noise at every position
    k = np.arange(N_FFT)
    for position in np.arange(39.0, 41.01, 0.1):
        tone = np.exp(2j * math.pi * position * k / N_FFT)[None, :].astype(np.complex64)
        bins = rd.range_fft(tone, suppress_clutter=False)[:, BINS]
        out = np.abs(bins @ h.conj())[0] ** 2
        best = float(flash_series.POSITION_STEP_BINS * int(np.argmax(out)) - 0.25 + 39.0)
        assert abs(best - position) <= flash_series.POSITION_STEP_BINS + 1e-9
        # a unit tone's energy is N against unit noise; three Hann bins keep 80 % of it when
        # centred (all N bins would undo the window) and at least 63 % between grid positions
        assert 0.63 * N_FFT <= out.max() <= 0.8 * N_FFT * (1.0 + 1e-4)


def test_coherent_checks_only_where_a_flash_fits_in_one_pri():
    paper, wide = get_preset("paper"), get_preset("wide")
    s = ref.flash_series(_slow(paper.n_chirps, [(100, 30.0, 0.3)]), paper.config, 0.0, 1.0, N_FFT)
    times, _ = ref.flash_events(s, s.radius)
    assert times.size >= 1 and ref._coherent(s, times) is not None
    s = ref.flash_series(_slow(wide.n_chirps, [(1000, 30.0, 0.3)]), wide.config, 0.0, 1.0, N_FFT)
    times, _ = ref.flash_events(s, s.radius)
    assert times.size >= 1 and ref._coherent(s, times) is None  # 6.25 us PRI: flashes span chirps


def test_coherent_hit_needs_the_same_profile_and_phase_up_to_sign():
    paper = get_preset("paper")
    # strong flash at 100; a weak same-hub flash one "period" later (sign flipped: sinc sidelobe);
    # an equally weak flash in quadrature at 400 (another rotor's random phase)
    flashes = [(100, 30.0, 0.3), (295, 4.0, 0.3 + np.pi), (400, 4.0, 0.3 + np.pi / 2)]
    s = ref.flash_series(_slow(paper.n_chirps, flashes, seed=1), paper.config, 0.0, 1.0, N_FFT)
    times = np.array([100.0])
    coh = ref._coherent(s, times)
    assert coh is not None and coh.share < 0.05
    hits = np.diff(coh.counts[0])
    assert hits[295] and not hits[400]
    weight = np.ones(1)
    found, made, chance = ref._coherent_checks(coh, times, weight, np.array([195.0, 300.0]), s.energy.size)
    assert found[0] == 1.0 and found[1] == 0.0 and np.all(made == 1.0) and np.all(chance < 0.5)


def test_periodicity_of_noise_and_of_nothing_is_quiet():
    paper = get_preset("paper")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for slow in (_slow(paper.n_chirps, [], seed=2), np.zeros((paper.n_chirps, 3), np.complex64)):
            per = ref.periodicity(ref.flash_series(slow, paper.config, 0.0, 1.0, N_FFT))
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
    s = ref.flash_series(_slow(paper.n_chirps, flashes, seed=4), paper.config, 0.0, 1.0, N_FFT)
    per = ref.periodicity(s)
    period = s.rate_hz / per.flash_rate.value
    assert abs(period - 195.0) <= 2.0


def test_flash_groups_merge_a_split_flash_and_count_distinct_ones():
    """A blade of several scatterers flashes as a cluster of peaks: one flash. Flashes further
    apart than the gap (3 % of the period, at least 3 samples) are distinct."""
    period = 200.0

    def groups(times: list[float]) -> int:
        return int(flash_period.flash_groups(np.array([times], dtype=float), np.array([period]))[0])

    assert groups([]) == 0
    assert groups([10.0, 12.0, 15.5]) == 1  # within 6 samples
    assert groups([10.0, 17.0, 100.0, 210.0]) == 4


def test_rotors_seen_counts_the_rotors_whatever_the_rotor_rate():
    """R rotors flashing once per period at spread phases, each flash split in two peaks, over a
    dwell of whole periods: R rotors seen at any period; a count's 1/sqrt uncertainty."""
    for rotors in (3, 4, 6, 8):
        for period in (150.0, 284.0, 611.0):
            periods = 3
            phases = (np.arange(rotors) + 0.5) / rotors
            t = np.sort(np.concatenate([(phases + m) * period + split for m in range(periods) for split in (0, 1.5)]))
            groups = int(flash_period.flash_groups(t[None, :], np.array([period]))[0])
            value, std = flash_period.rotors_seen(np.array([groups]), np.array([period]), int(periods * period))
            assert groups == rotors * periods
            assert value[0] == np.float64(rotors) or abs(value[0] - rotors) < 1e-9
            assert abs(std[0] - rotors / math.sqrt(groups)) < 1e-9
    value, std = flash_period.rotors_seen(np.array([0]), np.array([100.0]), 600)
    assert (value[0], std[0]) == (0.0, 0.0)


def test_rotors_seen_of_a_batch_is_the_reference_row_by_row():
    """The product's rotors seen is array-first: each row of a batch (its own events and period) is
    the per-return reference's count to the bit, one row as a batch of one included."""
    rng = np.random.default_rng(5)
    times = np.sort(rng.uniform(0.0, 1400.0, (40, 12)), axis=1)
    times[:, 1::2] = times[:, ::2] + rng.uniform(0.0, 12.0, (40, 6))  # split flashes, some within the gap
    times.sort(axis=1)
    period = rng.uniform(60.0, 400.0, 40)
    period[:3] = (0.0, -1.0, 80.0)  # no period: nothing seen
    groups = flash_period.flash_groups(times, period)
    value, std = flash_period.rotors_seen(groups, period, 1400)
    for b in range(times.shape[0]):
        want = ref.rotors_seen(ref.flash_groups(times[b], float(period[b])), float(period[b]), 1400)
        assert groups[b] == ref.flash_groups(times[b], float(period[b]))
        assert (value[b], std[b]) == (want.value, want.std)
        one = flash_period.rotors_seen(groups[b:b + 1], period[b:b + 1], 1400)
        assert (one[0][0], one[1][0]) == (want.value, want.std)


def _coned_series(offsets: tuple[float, ...], period: float = 340.0, split: float = 8.0,
                  n: int = 1400) -> ref.FlashSeries:
    """An event-path series (no complex field, `wide`'s 25 kHz): rotors at `offsets` whose two
    blades flash alternately on time and `split` samples late (coned blades seen off the rotor
    plane: 2.4 % of the period here), one sample each, all at one range position."""
    e = np.zeros(n)
    per_bin = np.full((n, 3), 1e-3)
    for off in offsets:
        for k in range(int((n - 1 - off) // period) + 1):
            t = int(round(off + k * period + (split if k % 2 else 0.0)))
            if t < n - 1:
                e[t], per_bin[t] = 100.0, (10.0, 100.0, 10.0)
    return ref.FlashSeries(e, per_bin, 25_000.0, 2, 0.0, threshold=1.0)


def test_event_search_tolerates_coned_blades_and_refines_the_period(monkeypatch):
    """Flash intervals alternating period +- 2.4 %: within 1 % of the lag the one-period partners
    are missed and twice the period wins (half the rate, twice the rotors); the 3 % search finds
    the period, and the refined, closely matched intervals put it within 0.5 % (their mean)."""
    for offsets in ((5.0, 71.0, 190.0, 251.0), (3.0, 50.0, 140.0, 300.0)):
        s = _coned_series(offsets)
        per = ref.periodicity(s)
        assert abs(s.rate_hz / per.flash_rate.value - 340.0) <= 0.005 * 340.0
        assert 3.5 <= per.rotors_seen.value <= 4.5
        batch = flash_period.periodicity_batch(flash_series.FlashSeriesBatch(
            np.stack([s.energy] * 8), np.stack([s.per_bin] * 8),
            np.full(8, s.threshold), np.zeros(8), None, None,
            s.rate_hz, s.radius, 1))
        assert np.all(batch.flash_rate_hz == per.flash_rate.value)
        with monkeypatch.context() as m:
            m.setattr(ref, "EVENT_TOL_FRACTION", flash_period.TOL_FRACTION)
            narrow = ref.periodicity(s)
        assert abs(s.rate_hz / narrow.flash_rate.value - 680.0) <= 2.0


@settings(max_examples=25, deadline=None)
@given(peak_bin=st.integers(0, N_FFT - 1), n=st.integers(1, 200), exponent=st.integers(-20, 20),
       seed=st.integers(0, 2**16))
def test_subchirp_bins_are_the_windows_fft_bins_whatever_the_scale(peak_bin, n, exponent, seed):
    """The basis product gives what its docstring says: each window's Hann-windowed FFT of the
    chirp demodulated to `peak_bin`, at bins -1, 0, 1 (within float32 rounding of the largest);
    an exact power-of-two scale rides on the basis bit for bit, and the same products come out
    on one BLAS thread as on the default ones (the batch path runs on one)."""
    window = flash_series.subchirp_window(get_preset("paper").config, N_FFT)
    rng = np.random.default_rng(seed)
    x = (rng.standard_normal((n, N_FFT)) + 1j * rng.standard_normal((n, N_FFT))).astype(np.complex64)
    got = flash_series.subchirp_bins(x, peak_bin, window)
    k = np.arange(N_FFT)
    xd = x.astype(np.complex128) * np.exp(-2j * math.pi * peak_bin * k / N_FFT)
    want = np.stack([np.fft.fft(xd[:, o:o + window] * rd.hann(window), axis=1)[:, [-1, 0, 1]]
                     for o in flash_series.subchirp_offsets(N_FFT, window)], axis=1)
    assert got.shape == (n, flash_series.SUBCHIRP_WINDOWS, flash_series.SUBCHIRP_BINS) and got.dtype == np.complex64
    assert np.max(np.abs(got - want)) <= 1e-5 * np.max(np.abs(want))
    scale = math.ldexp(1.0, exponent)
    assert np.array_equal(flash_series.subchirp_bins(x, peak_bin, window, scale),
                          flash_series.subchirp_bins(x * np.float32(scale), peak_bin, window))
    with one_blas_thread():  # another thread count: the same products to float32 rounding
        one = flash_series.subchirp_bins(x, peak_bin, window)
    assert np.abs(one - got).max() <= 16 * np.finfo(np.float32).eps * np.abs(got).max()
