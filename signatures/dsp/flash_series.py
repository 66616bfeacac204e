"""The flash-energy series of blade-flash gates, array-first: B gates of returns that share a radar
configuration at once (one return is B = 1); the period search (`signatures.dsp.flash_period`) reads it.

Blade flashes: a blade seen broadside returns all its length in phase for ~30 us
(Chen's sinc); two opposite blades flash together, twice per turn, so one rotor
flashes at 2 f_rot (2 blades assumed, as the shipped profiles have). The flash is an impulse
in slow time whatever the Doppler does, so timing survives blade-tip aliasing.

The series: demodulate the target bins by the body Doppler, subtract a short moving average
(removes body, hubs and clutter: everything slow; then again in the radar's frame for a moving
target's clutter line, `clutter_pass`), pass the bins through whitened matched filters for a point
scatterer at fractional range positions (a broadside blade sits at its hub's range) and keep the
best position's energy -> flash-energy series e[n]; keep what stands out of the noise (median +
NOISE_MADS MADs).

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
flashes rise above the noise (accuracy figures in docs/estimators.md).

Row b of `flash_series_batch` equals the straightforward per-return form of the series
(tests/features/reference_flash.py, "the reference") applied to `slow[b]` and `body_hz[b]` to the
bit (tests/features/test_batch_estimators.py): the reference's expressions with a batch axis in
front (window sums, reductions and the matched-filter product along the same axes; the product
stacked, so BLAS sees the reference's per-row shape), rows in cache-sized chunks (CHUNK_BYTES).
Scratch memory stays under MEMORY_BUDGET_BYTES; the outputs grow with B (the matched-filter field,
kept only where the coherent checks run: ~53 kB a row in `paper`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from signatures.errors import SignaturesError
from signatures.radar import RadarConfig
from signatures.dsp.rd import hann
from signatures.dsp.stats import median_last

__all__ = ["MEMORY_BUDGET_BYTES", "FlashSeriesBatch", "clutter_pass", "flash_lobe_s", "flash_series_batch",
           "flashes_within_one_sample", "highpass_s", "matched_filters", "scaled_subchirp_basis",
           "squared_magnitude", "subchirp_bins", "subchirp_window", "sum_last_axis", "window_sums"]

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
#: Flash events are local maxima within +-EVENT_RADIUS series samples (the series' `radius`).
EVENT_RADIUS = 2
#: Matched-filter positions: every POSITION_STEP_BINS from a quarter bin before the first
#: target bin to a quarter bin after the last (hubs lie within about a bin of the body).
POSITION_STEP_BINS = 0.25
#: Main lobe of a two-blade flash (s): lambda / (2 v_tip), with v_tip this typical tip speed:
#: ~18 us at 77 GHz, ~0.4 ms at 3.3 GHz (`flash_lobe_s`). The coherent checks run only where
#: the PRI is longer: a flash is then seen in at most one chirp, or missed between two, and
#: the energy events miss many partners.
FLASH_TIP_MPS = 108.0
#: The high-pass spans at least this many flash lobes (`highpass_s`): at long wavelengths a
#: flash outlasts HIGHPASS_S and the high-pass would remove it with the body.
HIGHPASS_LOBES = 3.0
#: Sub-chirp windows (module docstring): this many, each this share of the ramp, where a ramp
#: lasts at least SUBCHIRP_MIN_LOBES flash lobes. Three windows of 0.6 ramp were the best of
#: 40-64 % windows, 2-5 of them, on the randomised world (docs/features.md).
SUBCHIRP_WINDOWS = 3
SUBCHIRP_SHARE = 0.6
SUBCHIRP_MIN_LOBES = 2.0
SUBCHIRP_BINS = 3
#: Scratch memory one call aims to stay under (bytes): larger batches run in row chunks.
MEMORY_BUDGET_BYTES = 256 * 2**20
#: The flash series runs in row chunks of about this much scratch memory: arrays that stay in the
#: CPU cache make the batched arithmetic ~1.5x faster than one pass over a large batch.
CHUNK_BYTES = 32 * 2**20


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


@dataclass(frozen=True)
class FlashSeriesBatch:
    """B flash series of equal length, one per gate (`flash_series_batch`)."""

    energy: np.ndarray  # float64 (B, n): flash energy above the noise, >= 0
    per_bin: np.ndarray  # float64 (B, n, bins): energy before the noise cut, per range bin
    threshold: np.ndarray  # float64 (B,): detection level subtracted from the energy
    drift_bins_per_sample: np.ndarray  # float64 (B,): body range migration
    field: np.ndarray | None  # complex (B, positions, chirps); None where the coherent checks never run
    field_peak: np.ndarray | None  # (B, chirps): the maximum over positions of |field|^2
    rate_hz: float
    radius: int
    decimation: int


def flash_series_batch(slow: np.ndarray, config: RadarConfig, body_hz: np.ndarray,
                       range_bin_m: float, n_fft: int) -> FlashSeriesBatch:
    """The reference's `flash_series` of every row of `slow` (B, chirps, bins), or (B, chirps, windows,
    bins) of sub-chirp windows, with its `body_hz[b]`."""
    slow = np.asarray(slow)
    body = np.asarray(body_hz, dtype=np.float64).reshape(-1)
    if slow.ndim not in (3, 4) or body.size != slow.shape[0]:
        raise SignaturesError(f"flash_series_batch needs slow (B, chirps, [windows,] bins) and body_hz (B,), got "
                              f"{slow.shape} and {body.shape}")
    b_rows, n, n_bins = slow.shape[0], slow.shape[1], slow.shape[-1]
    windows = slow.shape[2] if slow.ndim == 4 else 1
    dec = max(1, int(config.prf_hz // SERIES_RATE_HZ))
    m = (n // dec) * dec
    n_out = m // dec if m >= dec else n
    filters = matched_filters(n_bins, n_fft)
    n_pos = filters.shape[1]
    # else `_coherent` never reads it
    keep_field = flashes_within_one_sample(config.prf_hz / dec, dec, config.wavelength_m)
    cdt = np.result_type(slow.dtype, np.complex64)
    energy = np.empty((b_rows, n_out))
    per_bin = np.empty((b_rows, n_out, n_bins))
    threshold = np.empty(b_rows)
    # positions x chirps: `_coherent` reads whole chirp rows of one position
    field = np.empty((b_rows, n_pos, n), cdt) if keep_field else None
    rdt = np.empty(0, cdt).real.dtype
    field_peak = np.empty((b_rows, n), rdt) if keep_field else None
    per_row = n * windows * (n_bins * cdt.itemsize * 10 + n_pos * (cdt.itemsize + 16))
    step = max(1, min(MEMORY_BUDGET_BYTES, CHUNK_BYTES) // max(per_row, 1))
    for a in range(0, b_rows, step):
        sl = slice(a, min(a + step, b_rows))
        y, peak = _series_rows(slow[sl], body[sl], config, n_fft, dec, energy[sl], per_bin[sl], threshold[sl])
        if field is not None:
            field[sl], field_peak[sl] = y.transpose(0, 2, 1), peak
    drift = body * config.wavelength_m / 2.0 * config.pri_s * dec / range_bin_m
    return FlashSeriesBatch(energy, per_bin, threshold, drift, field, field_peak, config.prf_hz / dec,
                            EVENT_RADIUS, dec)


def _series_rows(slow: np.ndarray, body: np.ndarray, config: RadarConfig, n_fft: int, dec: int,
                 energy: np.ndarray, per_bin: np.ndarray,
                 threshold: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reference's `flash_series` of a chunk of rows, written into the output views; returns the
    matched-filter field and its power's maximum over positions per chirp. Same
    expressions as the reference with a leading batch axis."""
    g, n, n_bins = slow.shape[0], slow.shape[1], slow.shape[-1]
    windows = slow.shape[2] if slow.ndim == 4 else 1
    t = np.arange(n)
    demod = np.exp((-2j * math.pi * body * config.pri_s)[:, None] * t).astype(np.complex64)
    z0 = slow.reshape(g, n, windows * n_bins) * demod[:, :, None]
    length = max(3, int(round(highpass_s(config.wavelength_m) / config.pri_s)) | 1)
    if n > length:
        clutter = clutter_pass(body, config.pri_s, length)
        z = _clutter_pass(_highpass(z0, length), demod, length, clutter)
        e1 = sum_last_axis(squared_magnitude(z))
        # the reference compares with a Python float: in e1's dtype (NEP 50)
        strong = e1 > _noise_level(e1).astype(e1.dtype)[:, None]
        strong[:, 1:] |= strong[:, :-1].copy()
        strong[:, :-1] |= strong[:, 1:].copy()
        z = _clutter_pass(_highpass(z0, length, ~strong), demod, length, clutter, ~strong)
    else:
        z = z0 - z0.mean(axis=1, keepdims=True)
    filters = matched_filters(n_bins, n_fft).conj().astype(z.dtype)
    m = (n // dec) * dec
    if slow.ndim == 4:  # each chirp: the window whose best position holds the most energy
        y4 = (z.reshape(g, n * windows, n_bins) @ filters).reshape(g, n, windows, -1)  # the reference's product
        best = _max_last(squared_magnitude(y4))  # the same floats as the reference's
        pick = np.argmax(best, axis=2)
        peak = np.take_along_axis(best, pick[:, :, None], axis=2)[:, :, 0]  # the picked window's maximum
        at = (np.arange(g * n) * windows + pick.reshape(-1))  # a gather of the picked windows' rows
        z = np.take(z.reshape(g * n * windows, n_bins), at, axis=0).reshape(g, n, n_bins)
        y = np.take(y4.reshape(g * n * windows, -1), at, axis=0).reshape(g, n, -1)
        py = None  # only decimated series need it, and windows run undecimated (`paper`)
    else:
        y = z @ filters  # (g, chirps, positions)
        py = squared_magnitude(y)
        peak = _max_last(py)
    eb = squared_magnitude(z).astype(np.float64)
    if m >= dec and dec > 1:
        eb = eb[:, :m].reshape(g, -1, dec, n_bins).sum(axis=2)
        py = (squared_magnitude(y) if py is None else py).astype(np.float64)
        e = _max_last(py[:, :m].reshape(g, -1, dec, py.shape[2]).sum(axis=2))
    else:  # the maximum of the float64 copies is the float64 copy of the maximum
        e = peak.astype(np.float64)
    level = _noise_level(e)
    energy[:] = np.maximum(e - level[:, None], 0.0)
    per_bin[:] = eb
    threshold[:] = level
    return y, peak


def _clutter_pass(z: np.ndarray, demod: np.ndarray, length: int, rows: np.ndarray,
                  keep: np.ndarray | None = None) -> np.ndarray:
    """Body-demodulated series z (rows, chirps, bins) with the rows where `rows` is True high-passed
    in the radar's frame too (`clutter_pass`). After the body's pass: a strong body line
    seen through the gaps of `keep` would leak into the radar frame's average at every flash."""
    if not rows.any():
        return z
    every = bool(rows.all())  # then in place, without a gather and a scatter
    d = (demod if every else demod[rows])[:, :, None]
    w = z if every else z[rows]
    w *= d.conj()
    w = _highpass(w, length, None if keep is None else (keep if every else keep[rows]))
    w *= d
    if every:
        return w
    z[rows] = w
    return z


def squared_magnitude(z: np.ndarray) -> np.ndarray:
    """z.real ** 2 + z.imag ** 2 (the same floats), on the contiguous interleaved view."""
    zz = np.ascontiguousarray(z)
    sq = zz.view(zz.real.dtype)
    sq = sq * sq
    return sq[..., 0::2] + sq[..., 1::2]


def sum_last_axis(x: np.ndarray) -> np.ndarray:
    """x.sum(axis=-1) for a short last axis, added left to right as numpy reduces it there,
    without numpy's per-row reduction overhead."""
    if x.shape[-1] >= 8:
        return x.sum(axis=-1)
    out = x[..., 0].copy()
    for j in range(1, x.shape[-1]):
        out += x[..., j]
    return out


def _max_last(x: np.ndarray) -> np.ndarray:
    """x.max(axis=-1) (exact in any order), one slice at a time."""
    out = x[..., 0].copy()
    for j in range(1, x.shape[-1]):
        np.maximum(out, x[..., j], out=out)
    return out


def _noise_level(e: np.ndarray) -> np.ndarray:
    """Per row of (rows, samples): the reference's `_noise_level` (median + NOISE_MADS MADs), float64."""
    med = median_last(e)
    mad = median_last(np.abs(e - med[:, None]))
    return med.astype(np.float64) + NOISE_MADS * 1.4826 * mad.astype(np.float64)


def _highpass(z: np.ndarray, length: int, keep: np.ndarray | None = None) -> np.ndarray:
    """The reference's `_highpass` along axis 1 of (rows, chirps, bins), `keep` (rows, chirps)."""
    g, n, n_bins = z.shape
    half = length // 2
    if keep is None:
        zk = z
    else:  # np.where(keep, z, 0) by zeroing the few chirps left out
        zk = z.copy()
        zk[~keep] = 0
    sums = window_sums(zk, half, axis=1)
    if keep is None:
        t = np.arange(n)
        count = (np.minimum(t + half + 1, n) - np.maximum(t - half, 0))[None, :]
    else:
        ck = np.zeros((g, n + 1), np.int64)
        np.cumsum(keep, axis=1, out=ck[:, 1:])
        count = _window_diff(ck, half, n)
        bi, ti = np.nonzero(count < max(2, length // 2))
        if bi.size:  # thin windows: the 4x longer one, summed for the rows that have them
            rows, at = np.unique(bi, return_inverse=True)
            sums[bi, ti] = window_sums(zk[rows], 2 * length, axis=1)[at, ti]
            lo2, hi2 = np.maximum(ti - 2 * length, 0), np.minimum(ti + 2 * length + 1, n)
            count[bi, ti] = ck[bi, hi2] - ck[bi, lo2]
        count = np.maximum(count, 1)
    return _minus_mean(z, sums, count)


def _minus_mean(z: np.ndarray, sums: np.ndarray, count: np.ndarray) -> np.ndarray:
    """z - sums / count as the reference computes it (a complex array over a float32 count), in
    place in `sums`. numpy divides by the complex (count + 0j) as Smith's algorithm does with a zero
    ratio: both parts times the reciprocal 1 / count in z's real precision (the same floats but
    for the sign of a zero real part, which nothing downstream reads); here on the interleaved
    real view, two passes without temporaries instead of a complex division."""
    rdt = z.real.dtype
    recip = np.reciprocal(count.astype(np.float32).astype(rdt))
    parts = sums.view(rdt).reshape(sums.shape + (2,))
    np.multiply(parts, recip[:, :, None, None], out=parts)
    return np.subtract(z, sums, out=sums)


def _window_diff(c: np.ndarray, half: int, n: int) -> np.ndarray:
    """c[:, hi] - c[:, lo] for hi = min(t + half + 1, n), lo = max(t - half, 0), t = 0..n-1: one
    subtraction of shifted slices where neither end clips, the clipped windows apart."""
    out = np.empty((c.shape[0], n) + c.shape[2:], c.dtype)
    b = min(n, half + 1)  # t < b: lo = 0
    a = max(b, n - half)  # t >= a: hi = n
    np.subtract(c[:, b + half + 1:a + half + 1], c[:, b - half:a - half], out=out[:, b:a])
    t = np.r_[0:b, a:n]
    out[:, t] = c[:, np.minimum(t + half + 1, n)] - c[:, np.maximum(t - half, 0)]
    return out
