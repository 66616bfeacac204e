"""The blade-flash estimators' algorithm, constants and shared primitives (the array-first
implementation is `signatures.flash`): flash rate, rotor rate, rotor count, rotors seen.

Blade flashes: a blade seen broadside returns all its length in phase for ~30 us
(Chen's sinc); two opposite blades flash together, twice per turn, so one rotor
flashes at 2 f_rot (2 blades assumed, as the shipped profiles have). The flash is an impulse
in slow time whatever the Doppler does, so timing survives blade-tip aliasing.

Pipeline: demodulate the target bins by the body Doppler, subtract a short
moving average (removes body, hubs and clutter: everything slow; then again in the radar's
frame for a moving target's clutter line, `clutter_pass`), pass the bins
through whitened matched filters for a point scatterer at fractional range
positions (a broadside blade sits at its hub's range) and keep the best
position's energy -> flash-energy series e[n]; keep what stands out of the noise;
find flash events (local maxima) and their range positions; score each
candidate period L by how consistently the events repeat at +-L: every event
whose partner window lies inside the dwell checks for a same-place event there,
and the share of checks that succeed is tested against the chance share (a
binomial log-likelihood ratio). All rotors of an airframe share the rate
(phases differ), so at the true period every rotor's checks succeed, while an
inter-rotor lag or a sub-multiple is refuted by the rotors that do not fit it. Flashes are treated as events, not
weighted by energy: in the `paper` preset a two-blade flash (main lobe ~20 us)
sampled once per 44 us PRI varies by up to ~20 dB with where it falls between
chirps, and energy-weighted autocorrelations then lock onto the few strongest
flashes of different rotors (inter-rotor lags).

Sub-chirp windows: where a ramp lasts over twice a flash's main lobe (`paper`: 44 us
against ~18 us), the flash is a burst inside the ramp, and the Hann window of the whole
chirp weighs it by where it falls: a flash near either end of the ramp almost vanishes
and a blade-tip floor then buries it. The target's three range bins are taken instead
from SUBCHIRP_WINDOWS shorter Hann windows (SUBCHIRP_SHARE of the ramp, spread evenly
over it) and each chirp keeps the window whose best position holds the most energy:
one sample per chirp as before (the period search is unchanged), but every flash seen
near its peak. The bins are the full-chirp peak bin and its neighbours on the shorter
window's coarser grid (`subchirp_bins`).

Matched filter: the Hann-windowed range bins of a point scatterer have a known
complex profile for each fractional position, and the window correlates the noise
of neighbouring bins (-2/3 between adjacent ones). Summing |.|^2 over three bins
adds three bins of (correlated) noise to one scatterer's energy; the whitened
matched filter for the scatterer's position keeps its energy in those bins against
one complex degree of freedom of noise, and the maximum over positions 1/4 bin
apart loses little of it: at low SNR that margin decides whether a rotor's weakest
flashes rise above the noise (accuracy figures in the README).

Coherent partner checks: the flashes of one rotor come from the same hub, so they
share its range position and, a period later, its carrier phase up to the
sign of the sinc (the body Doppler is removed; wobble moves the hub little within a
period). The event's matched-filter output, kept in phase with it, finds that
rotor's weaker flashes below the energy threshold, while
another rotor's flash (another hub range, a random phase) mostly fails it. These
checks re-rank the best candidate periods of the event vote and decide whether half
the chosen period is the period (in `paper` a flash one period later is often sampled
between chirps and missed, so twice the period can win the event vote).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from signatures.radar import RadarConfig
from signatures.rd import hann

#: Search range of the blade-flash rate (Hz): rotor rates 15-250 Hz with 2 blades.
FLASH_RATE_MIN_HZ = 30.0
FLASH_RATE_MAX_HZ = 500.0
#: Flash-energy series sample rate target (Hz): decimate the `wide` PRF to ~20 kHz.
SERIES_RATE_HZ = 25_000.0
#: High-pass length (s): longer than a flash, shorter than hub / body Doppler cycles (the
#: floor of `highpass_s`, which grows with the flash lobe at longer wavelengths).
HIGHPASS_S = 0.4e-3
#: The high-pass runs in the radar's frame too (the clutter's line, at zero Doppler) after the
#: body's, unless the body's line lies within this share of PRF / length of zero: the body's
#: pass then takes the clutter's line down by 20 dB or more (a running mean's response there is
#: 0.9), and one pass serves both (a hovering target, a CW body read at zero Doppler).
CLUTTER_PASS_SHARE = 0.25
#: Flash energy must exceed the series median by this many (normal-scaled) MADs:
#: ~1e-4 false flashes per sample for the chi-square noise of a few range bins.
NOISE_MADS = 5.0
#: Two flashes of one rotor lie within this many range bins of each other (after migration).
POSITION_TOL_BINS = 0.3
#: A period needs this share of the series overlapping itself.
MIN_OVERLAP = 1.0 / 3.0
#: Partner tolerance (series samples): TOL_SAMPLES + TOL_FRACTION * lag (timing +-0.5
#: sample, per-rotor rate spread 0.5 % std).
TOL_SAMPLES = 1.0
TOL_FRACTION = 0.01
#: The period search's tolerance where flashes span several chirps (no coherent checks:
#: `wide`): per-rotor rates differ by a few percent, and coned blades seen off the rotor plane
#: flash apart, alternately early and late by up to ~3 % of the period. The chosen lag (a
#: plateau's centre) is then refined by the mean of the intervals matching its multiples, and
#: the period is matched again within TOL_FRACTION: the search's margin would otherwise let
#: other rotors' intervals bias the period. 3 % was chosen on the randomised world among 1-5 %
#: (`wide` flash rate within 5 % at 0/10 dB: 88/85 -> 92/88 %, seed 9, and 87/89 -> 92/92 %, seed
#: 21); its price in the training world: 3 of 450 returns read at twice the rate (docs/features.md).
#: The coherent path keeps 1 % (3 % cost `paper` 3-6 points in its own world).
EVENT_TOL_FRACTION = 0.03
#: Events this many dB above the detection threshold vote fully; weaker ones (possibly
#: noise) proportionally less, down to MIN_VOTE_WEIGHT.
FULL_VOTE_DB = 10.0
MIN_VOTE_WEIGHT = 0.2
#: Half the chosen lag replaces it when at least this share (and SUBHARMONIC_MIN_FOUND)
#: of its partner checks succeed. In `paper` a flash (~1 PRI) one period apart is
#: sampled at another offset within the PRI and is often missed at 0 dB, while one two
#: periods apart may be sampled alike (phantom4: period ~194.5 chirps), so twice the
#: period can score above it; a chance half-period alignment of some rotors succeeds
#: in fewer checks than the true period's.
SUBHARMONIC_SHARE = 0.45
#: Score weight of a same-place flash pair two periods apart (one period apart = 1).
SECOND_PERIOD_GAIN = 0.3
SUBHARMONIC_MIN_FOUND = 3
#: ... unless the half's share falls below the lag's by more than this many standard errors
#: (a chance alignment of some rotors repeats less reliably than the true period). Not 2: a
#: rotor's weaker blade (unequal blades; coned ones seen off the rotor plane flash apart, each
#: alone) flashes less reliably than the same blade a turn later, so a true half fails more
#: checks than its double. 3 was chosen on the randomised world (`wide` flash rate within 5 %
#: 81/80 -> 88/85 % at 0/10 dB, training world unchanged; docs/features.md).
SUBHARMONIC_Z = 3.0
#: Flash events: local maxima within +-EVENT_RADIUS series samples, and above the sinc
#: skirt of every stronger event within SKIRT_REACH samples: SKIRT_DB - 20 log10(distance).
EVENT_RADIUS = 2
SKIRT_REACH = 12
SKIRT_DB = -13.0
BLADES_ASSUMED = 2
#: Matched-filter positions: every POSITION_STEP_BINS from a quarter bin before the first
#: target bin to a quarter bin after the last (hubs lie within about a bin of the body).
POSITION_STEP_BINS = 0.25
#: Coherent partner check: a partner is found where the event's matched-filter output, in
#: phase with the event (1 degree of freedom), has a power that exceeds this many
#: noise levels (noise alone: ~2.5 % of samples; the chance share is measured per series).
COHERENT_LEVEL = 5.0
#: The best RERANK_N candidate lags of the event vote are re-scored by
#: vote + RERANK_WEIGHT x share x coherent log-likelihood ratio.
RERANK_N = 10
RERANK_WEIGHT = 2.0
#: Half the lag replaces it when its coherent partner checks favour "found as often as at
#: the lag" over chance by this log-likelihood ratio.
HALF_LLR = 2.0
#: The lag's found share is capped at this for that test (a lag found everywhere would
#: otherwise make one miss at the half decisive).
HALF_SHARE_CAP = 0.98
#: The coherent hit must also hold this share of the best position's energy (phase agrees).
COHERENT_SHARE = 0.5
#: Main lobe of a two-blade flash (s): lambda / (2 v_tip), with v_tip this typical tip speed:
#: ~18 us at 77 GHz, ~0.4 ms at 3.3 GHz (`flash_lobe_s`). The coherent checks run only where
#: the PRI is longer: a flash is then seen in at most one chirp, or missed between two, and
#: the energy events miss many partners.
FLASH_TIP_MPS = 108.0
#: Flash events kept per series (the strongest): MAX_EVENTS, and this many per second of
#: dwell beyond it (64 in the `paper` and `wide` dwells of 26 and 51 ms; ~1,000 in 0.82 s).
MAX_EVENTS = 64
MAX_EVENTS_PER_S = 1200.0
#: The high-pass spans at least this many flash lobes (`highpass_s`): at long wavelengths a
#: flash outlasts HIGHPASS_S and the high-pass would remove it with the body.
HIGHPASS_LOBES = 3.0
#: Rotors seen: events closer than this share of the flash period (at least GROUP_GAP_SAMPLES)
#: are one flash. A blade made of several scatterers flashes as a cluster of peaks, while one
#: rotor flashes once per period and per-rotor rates differ by a few per cent.
GROUP_GAP_PERIODS = 0.03
GROUP_GAP_SAMPLES = 3.0
#: Sub-chirp windows (module docstring): this many, each this share of the ramp, where a ramp
#: lasts at least SUBCHIRP_MIN_LOBES flash lobes. Three windows of 0.6 ramp were the best of
#: 40-64 % windows, 2-5 of them, on the randomised world (docs/features.md).
SUBCHIRP_WINDOWS = 3
SUBCHIRP_SHARE = 0.6
SUBCHIRP_MIN_LOBES = 2.0
SUBCHIRP_BINS = 3


@dataclass(frozen=True)
class Estimate:
    """A value with a one-sigma uncertainty (both finite; value 0 and std 0 when absent)."""

    value: float
    std: float


@dataclass(frozen=True)
class FlashSeries:
    energy: np.ndarray  # float64 (n,), flash energy above the noise, >= 0
    per_bin: np.ndarray  # float64 (n, bins): the energy before the noise cut, per range bin
    rate_hz: float  # sample rate of the series
    radius: int  # samples either side a flash can spread over
    drift_bins_per_sample: float  # body range migration (bins per series sample)
    threshold: float = 0.0  # detection level subtracted from the energy (median + NOISE_MADS MAD)
    field: np.ndarray | None = None  # complex (chirps, positions): matched-filter outputs of the
    # high-passed, body-demodulated bins (noise: unit variance per position)
    decimation: int = 1  # chirps per series sample


def subchirp_window(config: RadarConfig, n_samples: int, domain: str = "if") -> int:
    """Samples per sub-chirp window for IF cubes of this waveform; 0 where the whole chirp is
    the window (a ramp shorter than SUBCHIRP_MIN_LOBES flash lobes, or no fast time)."""
    if domain != "if" or config.ramp_s < SUBCHIRP_MIN_LOBES * flash_lobe_s(config.wavelength_m):
        return 0
    w = int(round(SUBCHIRP_SHARE * n_samples))
    return w if SUBCHIRP_BINS <= w < n_samples else 0


@lru_cache(maxsize=16)
def subchirp_offsets(n_samples: int, window: int) -> tuple[int, ...]:
    """First sample of each sub-chirp window: SUBCHIRP_WINDOWS spread evenly over the ramp (cached:
    `linspace` costs more than a row's window products)."""
    return tuple(np.round(np.linspace(0, n_samples - window, SUBCHIRP_WINDOWS)).astype(int).tolist())


#: Chirps per matrix product in `subchirp_bins`: small enough (64 x 80 by 80 x 9 for `paper`)
#: that OpenBLAS runs it on one thread (measured, OpenBLAS 0.3.31: products of 128-256 chirps were
#: split among threads and then gave other last bits than on one; on a busy 2-core machine a woken
#: second thread cost up to 5 ms per return). On one thread the single and the batch paths make
#: the same products and get the same bits (tests/features/test_estimators_flash.py).
SUBCHIRP_BLOCK = 64


@lru_cache(maxsize=256)
def subchirp_basis(n_samples: int, peak_bin: int, window: int) -> np.ndarray:
    """(n_samples, SUBCHIRP_WINDOWS * SUBCHIRP_BINS) complex128, read-only: column (i, c) takes
    sub-chirp window i (Hann, from `subchirp_offsets`) of a chirp demodulated so that range bin
    `peak_bin` moves to 0, to its window-grid bin c - SUBCHIRP_BINS // 2. Phases reduced exactly
    (integer arithmetic) before the float ones."""
    k = np.arange(n_samples)
    demod = np.exp(-2j * math.pi * (peak_bin * k % n_samples) / n_samples)
    j = np.arange(window)
    cols = (np.arange(SUBCHIRP_BINS) - SUBCHIRP_BINS // 2) % window
    twiddle = np.exp(-2j * math.pi * (np.outer(j, cols) % window) / window)
    w = hann(window).astype(np.float64)
    basis = np.zeros((n_samples, SUBCHIRP_WINDOWS, SUBCHIRP_BINS), np.complex128)
    for i, o in enumerate(subchirp_offsets(n_samples, window)):
        basis[o:o + window, i] = (demod[o:o + window] * w)[:, None] * twiddle
    basis = basis.reshape(n_samples, -1)
    basis.flags.writeable = False
    return basis


def scaled_subchirp_basis(n_samples: int, peak_bin: int, window: int, dtype, scale: float = 1.0) -> np.ndarray:
    """`subchirp_basis` in the cube's complex `dtype` times the power of two `scale` (a fresh
    array): the products of `subchirp_bins`, which the batch path makes too."""
    basis = subchirp_basis(n_samples, peak_bin, window).astype(dtype)
    if scale != 1.0:
        basis *= basis.real.dtype.type(scale)
    return basis


def subchirp_bins(iq: np.ndarray, peak_bin: int, window: int, scale: float = 1.0) -> np.ndarray:
    """(chirps, SUBCHIRP_WINDOWS, SUBCHIRP_BINS): the bins around `peak_bin` of each sub-chirp
    window of the IF cube `iq` times `scale` (module docstring), in the cube's precision
    (complex64 at least). Not clutter-suppressed: the flash series' high-pass removes
    everything static. One matrix product with `subchirp_basis` (demodulation, windows and the
    three DFT bins in one), in blocks of SUBCHIRP_BLOCK chirps: 5x faster than the windows'
    full FFTs it replaced, of which it keeps 9 bins of 144 (values within 4e-7 of the largest).
    `scale`: an exact power of two (`rd.prepare`'s), folded into the basis, so the products round
    as those of the scaled cube."""
    x = np.asarray(iq)
    x = x if np.iscomplexobj(x) and x.dtype.itemsize >= 8 else x.astype(np.complex64)
    n, n_samples = x.shape
    basis = scaled_subchirp_basis(n_samples, peak_bin, window, x.dtype, scale)
    out = np.empty((n, basis.shape[1]), x.dtype)
    for s in range(0, n, SUBCHIRP_BLOCK):
        np.matmul(x[s:s + SUBCHIRP_BLOCK], basis, out=out[s:s + SUBCHIRP_BLOCK])
    return out.reshape(n, SUBCHIRP_WINDOWS, SUBCHIRP_BINS)


@lru_cache(maxsize=16)
def matched_filters(n_bins: int, n_fft: int) -> np.ndarray:
    """Whitened matched filters (complex128, n_bins x positions) for a point scatterer seen
    in `n_bins` adjacent bins of a periodic-Hann `n_fft`-point FFT, at positions every
    POSITION_STEP_BINS (module docstring). Filter h = C^-1 s / sqrt(s^H C^-1 s) for the
    scatterer's bin response s and the window's noise covariance C, so that |h^H z|^2 is
    the scatterer's energy and white input noise gives unit variance at every position.
    Cached, read-only."""
    k = np.arange(n_fft)
    w = hann(n_fft)  # the range FFT's own window
    bins = np.arange(n_bins)
    positions = np.arange(-0.25, n_bins - 0.75 + 1e-9, POSITION_STEP_BINS)
    # bin b of a tone at (fractional) bin p: sum_k w[k] exp(-2j pi (b - p) k / n_fft)
    response = np.exp(-2j * math.pi * (bins[:, None, None] - positions[None, :, None])
                      * k[None, None, :] / n_fft) @ w
    cov = np.exp(-2j * math.pi * (bins[:, None, None] - bins[None, :, None]) * k / n_fft) @ (w * w)
    h = np.linalg.solve(cov, response)
    h /= np.sqrt(np.maximum(np.real(np.sum(response.conj() * h, axis=0)), 1e-300))[None, :]
    h.setflags(write=False)
    return h


def _peak_positions(profiles: np.ndarray) -> np.ndarray:
    """Per row of (k, bins) energy profiles: the log-parabolic peak position (bins), the
    argmax where it sits at the edge or the parabola does not open downwards."""
    k = profiles.shape[0]
    out = np.argmax(profiles, axis=1).astype(np.float64) if k else np.zeros(0)
    if k == 0 or profiles.shape[1] < 3:
        return out
    idx = out.astype(int)
    inner = (idx > 0) & (idx < profiles.shape[1] - 1)
    if inner.any():
        rows = np.flatnonzero(inner)
        c = idx[rows]
        a, b, d = (np.log(np.maximum(profiles[rows, c + off].astype(np.float64), 1e-300)) for off in (-1, 0, 1))
        den = a - 2.0 * b + d
        shift = np.minimum(np.maximum(0.5 * (a - d) / np.where(den < 0, den, -1.0), -0.5), 0.5)
        out[rows] = np.where(den < 0, c + shift, c)
    return out


def max_events(dwell_s: float) -> int:
    """Flash events kept per series: MAX_EVENTS, or MAX_EVENTS_PER_S of the dwell where longer
    (a long dwell holds proportionally more flashes; a fixed cap would keep a few of them)."""
    return max(MAX_EVENTS, math.ceil(MAX_EVENTS_PER_S * dwell_s))


def flash_lobe_s(wavelength_m: float) -> float:
    """A flash's main lobe (s) at this wavelength: lambda / (2 FLASH_TIP_MPS)."""
    return wavelength_m / (2.0 * FLASH_TIP_MPS)


def highpass_s(wavelength_m: float) -> float:
    """The flash series' high-pass length (s): HIGHPASS_S, or HIGHPASS_LOBES flash lobes where
    flashes last longer, never beyond the fastest flash period (1 / FLASH_RATE_MAX_HZ)."""
    return min(max(HIGHPASS_S, HIGHPASS_LOBES * flash_lobe_s(wavelength_m)), 1.0 / FLASH_RATE_MAX_HZ)


def clutter_pass(body_hz: np.ndarray, pri_s: float, length: int) -> np.ndarray:
    """Per body Doppler (Hz): does the flash series high-pass the radar's frame (the clutter's
    line) after the body's? The body's line, aliased into +-PRF / 2, lies CLUTTER_PASS_SHARE x PRF /
    `length` or more from zero. Without it, swaying clutter (vegetation) left by the slow-time
    mean's removal stays in the series of a moving target as a floor that buries its flashes."""
    cycles = np.asarray(body_hz, dtype=np.float64) * pri_s
    return np.abs(cycles - np.round(cycles)) * length >= CLUTTER_PASS_SHARE


def window_sums(z: np.ndarray, half: int, axis: int = 0) -> np.ndarray:
    """Sums of z over the centred windows t - half .. t + half along `axis`, clipped at the ends
    (the flash series' moving averages). Interior windows add power-of-two partial sums, so a
    window's rounding scales with its own samples (log2 of the length additions), where a
    running-sum difference carries the rounding of everything before it in the dwell (float32:
    ~1e-7 of a strong clutter burst's total, enough to bury a flash 100 dB under it). The clipped
    ends are short running sums. About 2x faster than a cumulative-sum difference in numpy.
    Elementwise along the other axes: a row's sums do not depend on its batch."""
    n, length = z.shape[axis], 2 * half + 1
    def at(a: np.ndarray, s: slice) -> np.ndarray:
        return a[(slice(None),) * (axis % a.ndim) + (s,)]
    if half == 0:
        return z.copy()
    if n < length:  # every window clipped: a running-sum difference
        c = np.concatenate([np.zeros_like(at(z, slice(0, 1))), np.cumsum(z, axis=axis)], axis=axis)
        t = np.arange(n)
        return np.take(c, np.minimum(t + half + 1, n), axis=axis) - np.take(c, np.maximum(t - half, 0), axis=axis)
    out = np.empty_like(z)
    parts, width, p = [], 1, z  # p: sums of `width` consecutive samples
    while width <= length:
        if length & width:
            parts.append((p, width))
        if 2 * width <= length:
            p = at(p, slice(None, -width)) + at(p, slice(width, None))
        width *= 2
    m = n - length + 1  # interior windows
    acc, (first, off) = at(out, slice(half, half + m)), parts[-1]
    if len(parts) == 1:
        np.copyto(acc, at(first, slice(0, m)))
    for i, (p, w) in enumerate(reversed(parts[:-1])):  # widest first: the same floats as a chain of +
        np.add(at(first, slice(0, m)) if i == 0 else acc, at(p, slice(off, off + m)), out=acc)
        off += w
    head = np.cumsum(at(z, slice(0, 2 * half)), axis=axis)
    at(out, slice(0, half))[...] = at(head, slice(half, 2 * half))
    tail = np.cumsum(np.flip(at(z, slice(n - 2 * half, n)), axis=axis), axis=axis)
    at(out, slice(n - half, n))[...] = np.flip(at(tail, slice(half, 2 * half)), axis=axis)
    return out


def flashes_within_one_sample(rate_hz: float, decimation: int, wavelength_m: float) -> bool:
    """Does a flash (`flash_lobe_s`) fit within one PRI of a series at `rate_hz` decimated by
    `decimation` (the coherent checks' premise)?"""
    return rate_hz * max(1, decimation) * flash_lobe_s(wavelength_m) <= 1.0


def _binomial_llr(found: np.ndarray, made: np.ndarray, share: np.ndarray,
                  chance: np.ndarray) -> np.ndarray:
    """found of made checks at success share `share` against `chance`; 0 where share <= chance."""
    s = np.minimum(np.maximum(share, 1e-9), 1.0 - 1e-9)
    llr = found * np.log(s / chance) + (made - found) * np.log((1.0 - s) / (1.0 - chance))
    return np.where((s > chance) & (made > 0.0), llr, 0.0)


def _matched_intervals(diff: np.ndarray, lag: float | np.ndarray,
                       fraction: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(intervals over their multiple, matched mask, multiples) of the event pairs (diff: t_j - t_i,
    (k, k), or (rows, k, k) with `lag` broadcast against it, as the batch path calls it): matched
    where the interval lies within TOL_SAMPLES + fraction x (multiple x lag) of a multiple of `lag`."""
    mult = np.round(diff / lag)
    matched = (diff > 0) & (mult >= 1) & (np.abs(diff - mult * lag) <= TOL_SAMPLES + fraction * mult * lag)
    return diff / np.maximum(mult, 1), matched, mult


def flash_groups(times: np.ndarray, period: float) -> int:
    """Distinct flashes among time-sorted events: a gap wider than GROUP_GAP_PERIODS of the
    period (and GROUP_GAP_SAMPLES) starts a new one."""
    if times.size == 0:
        return 0
    gap = max(GROUP_GAP_SAMPLES, GROUP_GAP_PERIODS * period)
    return 1 + int(np.count_nonzero(np.diff(times) > gap))


def rotors_seen(groups: int, period: float, n: int) -> Estimate:
    """Rate-invariant rotor count: distinct flashes over the flash periods the dwell holds.

    Each rotor flashes once per flash period (the period is the time between its blades passing
    broadside), so flashes per period count the rotors whatever the rotor rate. Two rotors flashing
    within the group gap count once and missed flashes not at all, so it undercounts a little;
    its relative uncertainty is that of a count, 1 / sqrt(groups)."""
    if groups <= 0 or period <= 0.0 or n <= 0:
        return Estimate(0.0, 0.0)
    value = groups * period / n
    return Estimate(value, value / math.sqrt(groups))


