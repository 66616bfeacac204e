"""The blade-flash estimators, array-first: B gates of returns that share a radar configuration
at once (one return is B = 1). The algorithm is `signatures.estimators`'s (flash series,
periodicity, rotor count; docs/features.md); long dwells add the envelope spectrum
(`spectral_flash_rate`).

`flash_series_batch(slow[B, chirps, bins], ...)` then `periodicity_batch(series)`. Row b equals
the straightforward per-return form of the algorithm (tests/features/reference_flash.py, "the
reference") applied to `slow[b]` and `body_hz[b]` to the bit (tests/features/test_batch_estimators.py):
the same float operations on the same values in the same order, so that no discrete decision (an
event, a lag, a halving, a rotor group) depends on the batch. How:

* flash series: the reference's expressions with a batch axis in front (window sums,
  reductions and the matched-filter product along the same axes; the product stacked, so
  BLAS sees the reference's per-row shape); rows in cache-sized chunks (CHUNK_BYTES);
* flash events: the greedy sinc-skirt suppression is a loop over the candidates' rank
  (strongest first), vectorised over the rows still choosing;
* lag vote: rows grouped by their number of events k (no padding: (G, sign, lag, k)
  arrays); the partner lookup runs from event pairs (`_found`) instead of a `searchsorted`
  per event, and the weighted check sums are stacked matrix products with the reference's
  per-row shapes (BLAS sums in a shape-dependent order);
* plateau, re-rank candidates (a loop over the RERANK_N ranks) and the halving rule (a loop
  over halvings) over the whole batch; the coherent hits and checks per group of equal k
  (and equal candidate count); period statistics per group of equal match count (numpy's
  pairwise sums depend on the length).

Scratch memory stays under MEMORY_BUDGET_BYTES (row chunks); the outputs grow with B (the
matched-filter field, kept only where the coherent checks run: ~53 kB a row in `paper`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signatures import estimators as est
from signatures.errors import SignaturesError
from signatures.estimators import (
    COHERENT_LEVEL, COHERENT_SHARE, EVENT_RADIUS, EVENT_TOL_FRACTION, FLASH_RATE_MAX_HZ, FLASH_RATE_MIN_HZ,
    FULL_VOTE_DB, HALF_LLR, HALF_SHARE_CAP, MIN_OVERLAP, MIN_VOTE_WEIGHT, NOISE_MADS,
    POSITION_TOL_BINS, RERANK_N, RERANK_WEIGHT, SECOND_PERIOD_GAIN, SERIES_RATE_HZ, SKIRT_DB, SKIRT_REACH,
    SUBHARMONIC_MIN_FOUND, SUBHARMONIC_SHARE, SUBHARMONIC_Z, TOL_FRACTION, TOL_SAMPLES)
from signatures.radar import RadarConfig
from signatures.rotor_lines import count_known, visible_rotors
from signatures.stats import distinct

__all__ = ["MEMORY_BUDGET_BYTES", "FlashSeriesBatch", "PeriodicityBatch", "flash_series_batch",
           "periodicity_batch"]

#: Scratch memory one call aims to stay under (bytes): larger batches run in row chunks.
MEMORY_BUDGET_BYTES = 256 * 2**20
#: The flash series runs in row chunks of about this much scratch memory: arrays that stay in the
#: CPU cache make the batched arithmetic ~1.5x faster than one pass over a large batch.
CHUNK_BYTES = 32 * 2**20
#: Rows with the same number of events are processed in groups of about this much scratch: one
#: large group spends a third of the vote's time faulting in fresh pages; a few tens of MiB
#: reuse the allocator's memory.
GROUP_BYTES = 32 * 2**20
_SIGNS = np.array([1.0, -1.0])
#: Dwells at least this long take the flash rate from the envelope spectrum
#: (`spectral_flash_rate`): its bins are then <= 4 Hz, finer than the period search.
SPECTRAL_DWELL_S = 0.25
#: Harmonics of a candidate flash rate summed in the envelope spectrum.
SPECTRAL_HARMONICS = 4
#: A whitened envelope line this many times its floor is a line (`spectral_flash_rate`): a flash
#: train's fundamental, its first and third harmonics at half a candidate, a tagged blade's turn.
SPECTRAL_TAG_LINE = 10.0
#: A candidate's harmonic counts in its sum up to this many times its own line: a train's
#: fundamental is about its strongest line, and the whitening lifts high harmonics (their floor is
#: the noise, far under the skirt of the low ones), so uncapped, 2.5 F summed F's high harmonics.
HARMONIC_CAP = 10.0
#: The best candidate was a flash train's m-th harmonic where these multiples of best / m show
#: lines (`spectral_flash_rate`): its third (a tagged rotor's turn train: lines at f and 2 f under
#: 3 f), then its second (lines at the first and third harmonics of the half).
SUBHARMONIC_LINES = ((3, (1.0, 2.0)), (2, (1.0, 3.0)))
#: A tagged rotor's turn alternates sides, so the envelope difference carries it and the sum cancels
#: it: a turn line that divides a rate holds at least 1 / TURN_SHARE times the sum's power there
#: (`_turn_line`, `_turned`).
TURN_SHARE = 0.5
#: ... and the difference cancels the flash train's own line at twice the turn rate, where equal
#: blades seen in one half only (the other under the noise or cut) hold as much in the difference as
#: in the sum: a candidate turn that is no turn line (under 1 / TURN_SHARE of the sum) is not doubled
#: where the difference holds this share of the sum's power at twice it (`_one_sided`;
#: cw-on-11111111, training scene 5: 1.01 and 0.96, doubled before; tagged rotors with unequal
#: halves, cw-idle-10101010 training scenes 24 and 34: turn lines 7.8 and 4.5 over the sum, 0.6 and
#: 0.82 at twice them).
ONE_SIDED_SHARE = 0.8
#: A flash rate is divided by these where a part of it, and not the rate, shows a turn (`_turned`).
TURN_MULTIPLES = (2, 3)
#: Subtracted from the log peak-to-median of the (whitened) harmonic sum, so that >= 1 reads as
#: the period search's score does: noise and clutter alone score at most 0.08 over 300 `cw-sband`
#: dwells (0-20 dB, 0-40 dB clutter), tagged-blade quads 0.17-0.83 at the lowest of 30 and >= 1 in
#: 90 % of them in our world (tests/features/test_long_dwell.py).
SPECTRAL_NOISE_LOG = 1.2
#: A long dwell's rotors visible (`signatures.rotor_lines`) are a count: its std is one line (a
#: residue taken for a rotor, or two rotors at one phase taken for one).
VISIBLE_STD = 1.0
#: Bins per block of the whitening floor (`_whitened`).
SPECTRAL_FLOOR_BINS = 32
#: A CW dwell whose flash train scores this much is a detection: 5x the noise dwells' highest
#: (0.08). The verification reads a long dwell's rate from the same bar (`verify.MIN_SPECTRAL_SCORE`).
SPECTRAL_DETECT_SCORE = 0.4
#: Doppler (Hz) either side of the body line left out of the envelope at least: body, hub, clutter.
SPECTRAL_BODY_HZ = 20.0
#: Moving clutter (foliage, +20..+40 dB over the target) spreads the zero-Doppler line wider: the
#: envelope leaves out, besides, everything out to where the Doppler power (both sides, smoothed over
#: SPECTRAL_SMOOTH_HZ) falls to this many times its floor beyond SPECTRAL_BODY_HZ, within an eighth
#: of the PRF either side (3 was chosen on the randomised world among 3 and 10: its clutter spreads
#: 0-0.5 m/s; `line_width_hz`).
CLUTTER_FLOOR_FACTOR = 3.0
#: Share of a long dwell tapered (half at each end, a Tukey window) before its Doppler spectrum
#: (`flash_envelope`): the mean subtraction removes static clutter exactly, but clutter that moves,
#: or that an off-zero body demodulation moves (+20..+40 dB over the target), is not periodic in the
#: record, and a rectangular window's sidelobes carried it across the whole band, where no cut could
#: take it out (0.1 m/s of foliage read the clutter 489 Hz wide and drowned the flash line). The
#: rotors are counted on the untapered rest. Randomised world, 0.82 s hover / idle, 80 scenes: rate
#: within 3 % 69 / 61 -> 67 / 72, rotors within +-1 20 / 20 -> 31 / 32 (0.1 and 0.5 within 2 scenes
#: of that); the shortest keeps the most dwell for the count (training, 10 s hover / idle, 160
#: scenes: 150 / 146 untapered, 144 / 148 at 0.1, 150 / 150 at 0.05).
ENVELOPE_TAPER = 0.05
SPECTRAL_SMOOTH_HZ = 5.0


@dataclass(frozen=True)
class FlashSeriesBatch:
    """B flash series of equal length (row b as `estimators.FlashSeries`: `row(b)`)."""

    energy: np.ndarray  # float64 (B, n): flash energy above the noise, >= 0
    per_bin: np.ndarray  # float64 (B, n, bins): energy before the noise cut, per range bin
    threshold: np.ndarray  # float64 (B,): detection level subtracted from the energy
    drift_bins_per_sample: np.ndarray  # float64 (B,): body range migration
    field: np.ndarray | None  # complex (B, positions, chirps); None where the coherent checks never run
    field_peak: np.ndarray | None  # (B, chirps): the maximum over positions of |field|^2
    rate_hz: float
    radius: int
    decimation: int

    def row(self, b: int) -> est.FlashSeries:
        """Row b as the single-return series (what `estimators.flash_series` gives for it)."""
        return est.FlashSeries(self.energy[b], self.per_bin[b], self.rate_hz, self.radius,
                               float(self.drift_bins_per_sample[b]), float(self.threshold[b]),
                               None if self.field is None else self.field[b].T, self.decimation)


@dataclass(frozen=True)
class PeriodicityBatch:
    """Per row: what `features` takes from `estimators.periodicity` and `estimators.rotor_count`."""

    flash_rate_hz: np.ndarray  # (B,) float64, 0 where no periodicity
    flash_rate_std_hz: np.ndarray
    score: np.ndarray
    n_events: np.ndarray  # (B,) int
    flash_par_db: np.ndarray
    rotor_count: np.ndarray
    rotor_count_std: np.ndarray
    rotors_seen: np.ndarray  # `estimators.rotors_seen`: distinct flashes per flash period
    rotors_seen_std: np.ndarray


# --- flash series ---------------------------------------------------------------------------

def flash_series_batch(slow: np.ndarray, config: RadarConfig, body_hz: np.ndarray,
                       range_bin_m: float, n_fft: int) -> FlashSeriesBatch:
    """`estimators.flash_series` of every row of `slow` (B, chirps, bins), or (B, chirps, windows,
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
    filters = est.matched_filters(n_bins, n_fft)
    n_pos = filters.shape[1]
    # else `_coherent` never reads it
    keep_field = est.flashes_within_one_sample(config.prf_hz / dec, dec, config.wavelength_m)
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
    """`estimators.flash_series` of a chunk of rows, written into the output views; returns the
    matched-filter field and its power's maximum over positions per chirp. Same
    expressions as the reference with a leading batch axis."""
    g, n, n_bins = slow.shape[0], slow.shape[1], slow.shape[-1]
    windows = slow.shape[2] if slow.ndim == 4 else 1
    t = np.arange(n)
    demod = np.exp((-2j * math.pi * body * config.pri_s)[:, None] * t).astype(np.complex64)
    z0 = slow.reshape(g, n, windows * n_bins) * demod[:, :, None]
    length = max(3, int(round(est.highpass_s(config.wavelength_m) / config.pri_s)) | 1)
    if n > length:
        clutter = est.clutter_pass(body, config.pri_s, length)
        z = _clutter_pass(_highpass(z0, length), demod, length, clutter)
        e1 = _sum_last(_power(z))
        # the reference compares with a Python float: in e1's dtype (NEP 50)
        strong = e1 > _noise_level(e1).astype(e1.dtype)[:, None]
        strong[:, 1:] |= strong[:, :-1].copy()
        strong[:, :-1] |= strong[:, 1:].copy()
        z = _clutter_pass(_highpass(z0, length, ~strong), demod, length, clutter, ~strong)
    else:
        z = z0 - z0.mean(axis=1, keepdims=True)
    filters = est.matched_filters(n_bins, n_fft).conj().astype(z.dtype)
    m = (n // dec) * dec
    if slow.ndim == 4:  # each chirp: the window whose best position holds the most energy
        y4 = (z.reshape(g, n * windows, n_bins) @ filters).reshape(g, n, windows, -1)  # the reference's product
        best = _max_last(_power(y4))  # the same floats as the reference's
        pick = np.argmax(best, axis=2)
        peak = np.take_along_axis(best, pick[:, :, None], axis=2)[:, :, 0]  # the picked window's maximum
        at = (np.arange(g * n) * windows + pick.reshape(-1))  # a gather of the picked windows' rows
        z = np.take(z.reshape(g * n * windows, n_bins), at, axis=0).reshape(g, n, n_bins)
        y = np.take(y4.reshape(g * n * windows, -1), at, axis=0).reshape(g, n, -1)
        py = None  # only decimated series need it, and windows run undecimated (`paper`)
    else:
        y = z @ filters  # (g, chirps, positions)
        py = _power(y)
        peak = _max_last(py)
    eb = _power(z).astype(np.float64)
    if m >= dec and dec > 1:
        eb = eb[:, :m].reshape(g, -1, dec, n_bins).sum(axis=2)
        py = (_power(y) if py is None else py).astype(np.float64)
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
    in the radar's frame too (`estimators.clutter_pass`). After the body's pass: a strong body line
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


def _power(z: np.ndarray) -> np.ndarray:
    """z.real ** 2 + z.imag ** 2 (the same floats), on the contiguous interleaved view."""
    zz = np.ascontiguousarray(z)
    sq = zz.view(zz.real.dtype)
    sq = sq * sq
    return sq[..., 0::2] + sq[..., 1::2]


def _sum_last(x: np.ndarray) -> np.ndarray:
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
    """Per row of (rows, samples): `estimators._noise_level` (median + NOISE_MADS MADs), float64."""
    med = median_last(e)
    mad = median_last(np.abs(e - med[:, None]))
    return med.astype(np.float64) + NOISE_MADS * 1.4826 * mad.astype(np.float64)


def median_last(x: np.ndarray) -> np.ndarray:
    """`stats.median(x, axis=-1)`, the same values: one partition at the upper middle; for an even
    length the lower middle is the largest value below it (the same order statistic, ~4-6x faster)."""
    half = x.shape[-1] // 2
    part = np.partition(x, half, axis=-1)
    if x.shape[-1] % 2:
        return part[..., half]
    return (part[..., :half].max(axis=-1) + part[..., half]) / 2


def _highpass(z: np.ndarray, length: int, keep: np.ndarray | None = None) -> np.ndarray:
    """`estimators._highpass` along axis 1 of (rows, chirps, bins), `keep` (rows, chirps)."""
    g, n, n_bins = z.shape
    half = length // 2
    if keep is None:
        zk = z
    else:  # np.where(keep, z, 0) by zeroing the few chirps left out
        zk = z.copy()
        zk[~keep] = 0
    sums = est.window_sums(zk, half, axis=1)
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
            sums[bi, ti] = est.window_sums(zk[rows], 2 * length, axis=1)[at, ti]
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


# --- periodicity ----------------------------------------------------------------------------

def periodicity_batch(series: FlashSeriesBatch, max_events: int | None = None) -> PeriodicityBatch:
    """`estimators.periodicity` and `estimators.rotor_count` of every row.

    Stages that depend on the number of events k run per group of rows with the same k (the
    votes, the coherent hits and checks, the period); those on the lag axis alone (plateau,
    re-rank candidates, halving rule) run over the whole batch at once."""
    e = series.energy
    b_rows, n = e.shape
    if max_events is None:
        max_events = est.max_events(n / series.rate_hz)
    out = {name: np.zeros(b_rows) for name in ("rate", "std", "score", "par", "rotors", "rotors_std", "seen",
                                               "seen_std")}
    n_events = np.zeros(b_rows, dtype=int)
    if n >= 8:
        emax = e.max(axis=1)
        live = emax > 0.0
        mean = e.mean(axis=1)
        out["par"][:] = [10.0 * math.log10(max(a / max(b, 1e-300), 1.0)) if ok else 0.0
                         for a, b, ok in zip(emax.tolist(), mean.tolist(), live.tolist())]
        times, pos, k = _flash_events(e, series.threshold, series.per_bin, series.radius, max_events)
        n_events[:] = np.where(live, k, 0)
        lag_min = max(2.0, series.rate_hz / FLASH_RATE_MAX_HZ)
        lag_max = min(n * (1.0 - MIN_OVERLAP), series.rate_hz / FLASH_RATE_MIN_HZ)
        if lag_max > lag_min:
            lags = np.arange(math.ceil(lag_min), math.floor(lag_max) + 1, dtype=float)
            _periodic_rows(series, times, pos, k, live & (k >= 2), lags, out)
    return PeriodicityBatch(out["rate"], out["std"], out["score"], n_events, out["par"], out["rotors"],
                            out["rotors_std"], out["seen"], out["seen_std"])


def _periodic_rows(series: FlashSeriesBatch, times: np.ndarray, pos: np.ndarray, k: np.ndarray,
                   work: np.ndarray, lags: np.ndarray, out: dict[str, np.ndarray]) -> None:
    """The lag vote and everything after it for the rows in `work` (k >= 2 events), into `out`."""
    b_rows, n = series.energy.shape
    n_bins = series.per_bin.shape[2]
    dec = max(1, series.decimation)
    coherent = series.field is not None and series.field.shape[2] >= n * dec  # kept where flashes fit one PRI
    fraction = TOL_FRACTION if coherent else EVENT_TOL_FRACTION
    groups = []  # (k, batch rows) with the scratch of one group within the memory budget
    for kk in distinct(k[work]):
        rows = np.flatnonzero(work & (k == kk))
        per_row = 2 * lags.size * kk * 48 + (kk * n * dec * 40 if coherent else 0)
        step = max(1, min(MEMORY_BUDGET_BYTES, GROUP_BYTES) // per_row)
        groups += [(kk, rows[a:a + step]) for a in range(0, rows.size, step)]
    vote = np.zeros((b_rows, lags.size))
    found_n, valid_n = np.zeros_like(vote), np.zeros_like(vote)
    weight = np.zeros(times.shape)
    for kk, r in groups:
        t = times[r, :kk]
        ti = np.minimum(np.maximum(np.round(t).astype(int), 0), n - 1)
        strength = np.take_along_axis(series.energy[r], ti, axis=1) / np.maximum(series.threshold[r], 1e-300)[:, None]
        w = np.minimum(np.maximum(np.log10(1.0 + strength) * 10.0 / FULL_VOTE_DB, MIN_VOTE_WEIGHT), 1.0)
        weight[r, :kk] = w
        vote[r], found_n[r], valid_n[r] = _votes(t, pos[r, :kk], w, lags, n, series.drift_bins_per_sample[r],
                                                 n_bins, counts=not coherent, fraction=fraction)
    best = vote.max(axis=1)
    ok = work & (best > 0.0) & (found_n.max(axis=1) > 0.0)
    rows = np.flatnonzero(ok)
    if rows.size == 0:
        return
    at = np.full(b_rows, -1)
    at[rows] = np.arange(rows.size)
    v = vote[rows]
    i0 = np.argmax(v, axis=1)
    after = (np.arange(lags.size)[None, :] > i0[:, None]) & (v != best[rows, None])
    i1 = np.where(after.any(axis=1), np.argmax(after, axis=1), lags.size) - 1
    lag = 0.5 * (lags[i0] + lags[i1])  # the vote's best lag (centre of its plateau)
    if coherent:
        cands, scores, n_c = _rerank_candidates(v, lag, lags)
        for kk, r in groups:
            sub = r[ok[r]]
            if sub.size == 0:
                continue
            counts, share = _coherent(series.field[sub], series.field_peak[sub], times[sub, :kk], n, dec)
            lag[at[sub]] = _rerank_choose(counts, share, times[sub, :kk], weight[sub, :kk], cands[at[sub]],
                                          scores[at[sub]], n_c[at[sub]], lags, n)
    else:
        lag = _event_half_rule(lags, v, found_n[rows], valid_n[rows], lag, fraction)
    for kk, r in groups:
        sub = r[ok[r]]
        if sub.size == 0:
            continue
        rate, std, score, phases, tol, period = _period(times[sub, :kk], pos[sub, :kk],
                                                        series.drift_bins_per_sample[sub], lag[at[sub]],
                                                        series.rate_hz, n_bins, fraction)
        rotors, rotors_std = _rotor_count(phases, tol)
        seen = [est.rotors_seen(est.flash_groups(t, p), p, n) for t, p in zip(times[sub, :kk], period.tolist())]
        for name, values in (("rate", rate), ("std", std), ("score", score), ("rotors", rotors),
                             ("rotors_std", rotors_std), ("seen", [e.value for e in seen]),
                             ("seen_std", [e.std for e in seen])):
            out[name][sub] = values


def _flash_events(e: np.ndarray, threshold: np.ndarray, per_bin: np.ndarray, radius: int,
                  max_events: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`estimators.flash_events` of every row: times and positions (B, K) sorted by time in the
    first k[b] columns (inf after), and k (B,). The greedy skirt suppression runs over the
    candidates' rank (strongest first), vectorised over rows."""
    b_rows, n = e.shape
    pad = np.zeros((b_rows, n + 2 * radius))
    pad[:, radius:radius + n] = e
    wmax = pad[:, :n].copy()  # maximum over the window of +-radius (exact in any order)
    for j in range(1, 2 * radius + 1):
        np.maximum(wmax, pad[:, j:j + n], out=wmax)
    rows, cols = np.nonzero((e > 0.0) & (e >= wmax))
    order = np.lexsort((cols, -e[rows, cols], rows))  # per row: strongest first, ties by time
    rows, cols = rows[order], cols[order]
    n_cand = np.bincount(rows, minlength=b_rows)
    rank = np.arange(rows.size) - (np.cumsum(n_cand) - n_cand)[rows]
    width = int(n_cand.max()) if rows.size else 0
    cand = np.zeros((b_rows, width), dtype=int)
    cand[rows, rank] = cols
    raw = e + threshold[:, None]
    cand_raw = np.zeros((b_rows, width))
    cand_raw[rows, rank] = raw[rows, cols]
    by_count = np.argsort(-n_cand, kind="stable")  # the rows still choosing are a prefix of this order
    cand, cand_raw, n_sorted = cand[by_count], cand_raw[by_count], n_cand[by_count]
    kept = np.zeros((b_rows, max_events), dtype=int)
    kept_raw = np.zeros((b_rows, max_events))
    k = np.zeros(b_rows, dtype=int)
    skirt = 10.0 ** (SKIRT_DB / 10.0)
    slots = np.arange(max_events)
    for r in range(width):
        m = int(np.count_nonzero(n_sorted > r))
        act = k[:m] < max_events
        p = cand[:m, r]
        km = int(k[:m].max())
        if km:
            d = p[:, None] - kept[:m, :km]
            near = act[:, None] & (slots[:km] < k[:m, None]) & (np.abs(d) <= SKIRT_REACH)
            bound = kept_raw[:m, :km] * skirt / np.where(near, d * d, 1)
            act &= ~(near & ~(cand_raw[:m, r:r + 1] >= bound)).any(axis=1)
        idx = np.flatnonzero(act)
        kept[idx, k[idx]] = p[idx]
        kept_raw[idx, k[idx]] = cand_raw[idx, r]
        k[idx] += 1
    unsort = np.empty_like(by_count)
    unsort[by_count] = np.arange(b_rows)
    kept, k = kept[unsort], k[unsort]
    width = int(k.max()) if b_rows else 0
    peaks = kept[:, :width]
    valid = slots[:width] < k[:, None]
    lo, hi = np.maximum(peaks - 1, 0), np.minimum(peaks + 1, n - 1)
    el, ep, eh = (np.take_along_axis(e, i, axis=1) for i in (lo, peaks, hi))
    w = el + ep + eh
    centroid = (lo * el + peaks * ep + hi * eh) / np.maximum(w, 1e-300)
    profiles = np.take_along_axis(per_bin, peaks[:, :, None], axis=1)
    positions = est._peak_positions(profiles.reshape(-1, per_bin.shape[2])).reshape(peaks.shape)
    order = np.argsort(np.where(valid, centroid, np.inf), axis=1)
    times = np.where(valid, np.take_along_axis(centroid, order, axis=1), np.inf)
    return times, np.take_along_axis(positions, order, axis=1), k


def _weighted_sums(mask: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """(g, 2, m, k) checks weighted by (g, k) events, summed over events and both signs: (g, m).
    One stacked matrix product: each row's sums are the reference's `(mask @ weight).sum(axis=0)`
    to the bit (same BLAS call shape per row)."""
    return np.matmul(mask.astype(np.float64, copy=False), weight[:, None, :, None])[..., 0].sum(axis=1)


def _votes(times: np.ndarray, pos: np.ndarray, weight: np.ndarray, lags: np.ndarray, n: int,
           drift: np.ndarray, n_bins: int, counts: bool,
           fraction: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`estimators._votes` of a group (partner tolerance TOL_SAMPLES + fraction x lag): (vote,
    found_n, valid_n), each (g, lags). Without `counts`
    (only the halving rule reads them) found_n is the weighted count (zero where found_n is: every
    weight is >= MIN_VOTE_WEIGHT) and valid_n zero.

    The single path looks up, for every event, sign and lag, the two events next to the target
    t +- L (`searchsorted`). Here the lookup runs the other way round: event j is one of those two
    for target T exactly when t[j-1] < T <= t[j+1], and can only be found within the tolerance
    when |t[j] - t[i]| is within a few samples of L; so every pair of events is checked at the
    few lags near its interval, with the reference's expressions (same floats, same decisions).
    """
    g, k = times.shape
    informative = (pos > 0.0) & (pos < n_bins - 1)
    dt = times[:, None, :] - times[:, :, None]  # (g, i, j): t_j - t_i
    moved = pos[:, None, :] - pos[:, :, None] - drift[:, None, None] * dt
    compat = (np.abs(moved) <= POSITION_TOL_BINS) | ~informative[:, None, :] | ~informative[:, :, None]
    share_compat = (compat.sum(axis=(1, 2)) - k) / max(k * (k - 1), 1)
    tol = TOL_SAMPLES + fraction * lags
    t2 = tol[None, :, None]
    upper = n - 1 - t2
    # checks as the float64 0/1 copies the reference's matmul makes: found (+, -), valid (+, -).
    # Valid is `tol <= t +- L <= n - 1 - tol`; with 0 <= t <= n - 1 (centroids) and L >= 2 > tol + 0.98
    # one side always holds: t + L >= tol and t - L <= n - 1 - tol, so only the other is tested
    checks = np.empty((g, 4, lags.size, k))
    checks[:, :2] = 0.0
    checks[:, 2] = times[:, None, :] + lags[None, :, None] <= upper
    checks[:, 3] = times[:, None, :] + (-1.0 * lags)[None, :, None] >= t2
    _found(times, compat, lags, n, checks, fraction)
    w = np.matmul(checks, weight[:, None, :, None])[..., 0]  # per row the reference's (2, L, k) @ (k,)
    found_w, valid_w = w[:, 0] + w[:, 1], w[:, 2] + w[:, 3]
    if counts:
        c = np.matmul(checks, np.ones((g, 1, k, 1)))[..., 0]  # sums of 0/1: exact in any order
        found_n, valid_n = c[:, 0] + c[:, 1], c[:, 2] + c[:, 3]
    else:
        found_n, valid_n = found_w, np.zeros_like(valid_w)
    chance = np.minimum(np.maximum(1.0 - np.exp((-(k - 1) / n * 2.0 * tol)[None, :] * share_compat[:, None]),
                                   1e-3), 0.999)
    share = np.minimum(np.maximum(found_w / np.maximum(valid_w, 1e-12), 1e-9), 1.0 - 1e-9)
    llr = found_w * np.log(share / chance) + (valid_w - found_w) * np.log((1.0 - share) / (1.0 - chance))
    return np.where(share > chance, llr * share, 0.0), found_n, valid_n


def _found(times: np.ndarray, compat: np.ndarray, lags: np.ndarray, n: int, out: np.ndarray,
           fraction: float) -> None:
    """Set out[:, 0 or 1, L, i] = 1.0 where event i finds a position-compatible partner at t_i +- L
    (`_votes`)."""
    g, k = times.shape
    lag0, lag1 = float(lags[0]), float(lags[-1])
    reach = TOL_SAMPLES + fraction * lag1
    dt = times[:, None, :] - times[:, :, None]
    gi, ii, jj = np.nonzero(compat & (np.abs(dt) >= lag0 - reach) & (np.abs(dt) <= lag1 + reach))
    if gi.size == 0:
        return
    ti, tj = times[gi, ii], times[gi, jj]
    span = np.abs(tj - ti)
    # |span - L| <= TOL_SAMPLES + f L  =>  L in [(span - TOL_SAMPLES) / (1 + f), (span + TOL_SAMPLES) / (1 - f)];
    # one lag of margin either side for rounding: the exact test below decides
    first = np.maximum(np.ceil((span - TOL_SAMPLES) / (1.0 + fraction)) - 1.0, lag0)
    last = np.minimum(np.floor((span + TOL_SAMPLES) / (1.0 - fraction)) + 1.0, lag1)
    count = np.maximum(last - first + 1.0, 0.0).astype(int)
    pair = np.repeat(np.arange(gi.size), count)
    lag = first[pair] + (np.arange(pair.size) - np.repeat(np.cumsum(count) - count, count))
    inf = np.full((g, 1), np.inf)
    padded = np.concatenate([-inf, times, inf], axis=1)
    sign = np.where(tj > ti, 1.0, -1.0)
    # per pair: t_i, t_j, sign, and the times around t_j (event j is next to the target T exactly
    # when t[j-1] < T <= t[j+1]), gathered for every candidate lag in one go
    t_i, t_j, sgn, t_prev, t_next = np.take(np.stack([ti, tj, sign, padded[gi, jj], padded[gi, jj + 2]]), pair,
                                            axis=1)
    tol = TOL_SAMPLES + fraction * lag
    target = t_i + sgn * lag
    hit = np.flatnonzero((target >= tol) & (target <= n - 1 - tol) & (t_prev < target) & (target <= t_next)
                         & (np.abs(t_j - target) <= tol))
    # flat index into out (g, 4, lags, k): ((row 4 + sign) lags + L - lag0) k + i, per pair up to L
    base = ((gi * out.shape[1] + (sign < 0)) * lags.size - int(lag0)) * k + ii
    out.reshape(-1)[np.take(base, pair[hit]) + lag[hit].astype(int) * k] = 1.0


def _coherent(field: np.ndarray, total: np.ndarray, times: np.ndarray, n: int,
              dec: int) -> tuple[np.ndarray, np.ndarray]:
    """`estimators._coherent` of a group: hit counts (g, k, n + 1) and the chance share (g,).
    `field` is (g, positions, chirps), `total` its power's maximum over positions (`FlashSeriesBatch`)."""
    g, k = times.shape
    field, total = field[:, :, :n * dec], total[:, :n * dec]
    gi = np.arange(g)[:, None]
    ti = np.minimum(np.maximum(np.rint(times).astype(int), 0), n - 1)
    rows = ti * dec
    if dec > 1:
        block = field.reshape(g, -1, n, dec)[gi, :, rows // dec]  # (g, k, positions, dec)
        block = np.ascontiguousarray(block.transpose(0, 1, 3, 2))  # (g, k, dec, positions) as the reference
        rows = rows + np.argmax((block.real ** 2 + block.imag ** 2).sum(axis=3), axis=2)
    at_rows = np.take_along_axis(field, rows[:, None, :], axis=2)  # (g, positions, k)
    at = np.argmax(at_rows.real ** 2 + at_rows.imag ** 2, axis=1)  # (g, k): each event's best position
    own = field[gi, at, rows]
    phase = own / np.maximum(np.abs(own), 1e-30)
    # (g, k, n * dec): the same products as the reference's (n * dec, k) layout, to the bit
    power = np.square((field[gi, at] * phase.conj()[:, :, None]).real)
    coherent = power >= np.float32(COHERENT_SHARE) * total[:, None, :]
    if dec > 1:
        coherent = coherent.reshape(g, k, n, dec)
        power = power.reshape(g, k, n, dec)
        pick = np.argmax(np.where(coherent, power, np.float32(-1.0)), axis=3)[..., None]
        coherent = np.take_along_axis(coherent, pick, axis=3)[..., 0]
        power = np.take_along_axis(power, pick, axis=3)[..., 0]
    half = n // 2
    med = np.partition(power, half, axis=2)[:, :, half:half + 1]
    hit = coherent & (power > np.float32(COHERENT_LEVEL / 0.455) * np.maximum(med, np.float32(1e-30)))
    counts = np.zeros((g, k, n + 1), np.int32)
    np.cumsum(hit, axis=2, out=counts[:, :, 1:])
    lo, hi = np.maximum(ti - 2, 0), np.minimum(ti + 3, n)
    own_hits = (np.take_along_axis(counts, hi[:, :, None], axis=2)
                - np.take_along_axis(counts, lo[:, :, None], axis=2)).sum(axis=(1, 2)).astype(float)
    others = np.maximum((k * n - (hi - lo).sum(axis=1)).astype(float), 1.0)
    return counts, np.maximum(counts[:, :, -1].sum(axis=1).astype(float) - own_hits, 0.0) / others


def _coherent_checks(counts: np.ndarray, share: np.ndarray, times: np.ndarray, lags: np.ndarray,
                     n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`estimators._coherent_checks` with per-row lags (g, m), before the weighted sums: the checks
    made and succeeded (g, 2, m, k) and the chance (g, m)."""
    g, k = times.shape
    tol = TOL_SAMPLES + TOL_FRACTION * lags
    w = np.floor(tol + 0.5).astype(int)
    chance = np.minimum(np.maximum(1.0 - (1.0 - share[:, None]) ** (2 * w + 1), 1e-3), 0.999)
    target = times[:, None, None, :] + _SIGNS[None, :, None, None] * lags[:, None, :, None]
    t3, w3 = tol[:, None, :, None], w[:, None, :, None]
    ok = (target >= t3) & (target <= n - 1 - t3)
    centre = np.rint(target).astype(int)
    lo = np.minimum(np.maximum(centre - w3, 0), n)
    hi = np.minimum(np.maximum(centre + w3 + 1, 0), n)
    flat = counts.ravel()
    base = (np.arange(g) * k * (n + 1))[:, None, None, None] + (np.arange(k) * (n + 1))[None, None, None, :]
    return ok, ok & (flat[base + hi] > flat[base + lo]), chance


def _rerank_candidates(vote: np.ndarray, lag0: np.ndarray,
                       lags: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`estimators._rerank`'s greedy candidates for every row: (lags, vote scores) (rows, RERANK_N)
    and their number per row; a loop over the RERANK_N ranks."""
    g = vote.shape[0]
    gi = np.arange(g)
    left = np.where(vote > 0.0, vote, -np.inf)
    reach = TOL_SAMPLES + TOL_FRACTION * lags
    cands = np.zeros((g, RERANK_N))
    scores = np.zeros((g, RERANK_N))
    n_c = np.zeros(g, dtype=int)
    span = int(math.ceil(TOL_SAMPLES + TOL_FRACTION * float(lags[-1]) / (1.0 - TOL_FRACTION))) + 1
    offsets = np.arange(-span, span + 1)
    for r in range(RERANK_N):
        j = np.argmax(left, axis=1)
        top = left[gi, j]
        act = top > 0.0
        if not act.any():
            break
        cands[act, r] = lag0[act] if r == 0 else lags[j[act]]
        scores[act, r] = top[act]
        n_c += act
        # the lags within reach of lags[j] lie within `span` indices of j: test those only
        near = np.minimum(np.maximum(j[act, None] + offsets[None, :], 0), lags.size - 1)
        drop = np.abs(lags[near] - lags[j[act], None]) <= reach[near]
        left[np.repeat(gi[act], offsets.size)[drop.ravel()], near[drop]] = -np.inf
    return cands, scores, n_c


def _rerank_choose(counts: np.ndarray, share: np.ndarray, times: np.ndarray, weight: np.ndarray,
                   cands: np.ndarray, scores: np.ndarray, n_c: np.ndarray, lags: np.ndarray, n: int) -> np.ndarray:
    """`estimators._rerank`'s choice among each row's n_c candidates (rows with the same k),
    halving applied: the chosen lag per row. The checks run at the candidates padded to the
    most any row has; their weighted sums per number of candidates c, with the reference's
    (2, 3c, k) shapes (BLAS sums depend on the shape)."""
    g = cands.shape[0]
    cm = int(n_c.max())
    cl = np.where(np.arange(cm)[None, :] < n_c[:, None], cands[:, :cm], lags[0])  # padding: any lag
    ok, hit, chance = _coherent_checks(counts, share, times, np.concatenate([cl, 2.0 * cl, cl / 2.0], axis=1), n)
    found, made = np.zeros((g, 3 * cm)), np.zeros((g, 3 * cm))
    for c in distinct(n_c):
        sel = np.flatnonzero(n_c == c)
        cols = np.concatenate([np.arange(c), cm + np.arange(c), 2 * cm + np.arange(c)])
        found[sel[:, None], cols] = _weighted_sums(hit[sel][:, :, cols], weight[sel])
        made[sel[:, None], cols] = _weighted_sums(ok[sel][:, :, cols], weight[sel])
    f1, f2, fh = found[:, :cm], found[:, cm:2 * cm], found[:, 2 * cm:]
    m1, m2, mh = made[:, :cm], made[:, cm:2 * cm], made[:, 2 * cm:]
    s = (f1 + f2) / np.maximum(m1 + m2, 1e-12)
    llr = est._binomial_llr(f1, m1, s, chance[:, :cm]) + est._binomial_llr(f2, m2, s, chance[:, cm:2 * cm])
    total = np.where(np.arange(cm)[None, :] < n_c[:, None], scores[:, :cm] + RERANK_WEIGHT * s * llr, -np.inf)
    best = np.argmax(total, axis=1)
    si = np.arange(g)
    lag = cl[si, best]
    half = (lag / 2.0 >= lags[0]) & _half_is_period(f1[si, best], m1[si, best], fh[si, best], mh[si, best],
                                                    chance[si, 2 * cm + best])
    return np.where(half, lag / 2.0, lag)


def _half_is_period(found: np.ndarray, made: np.ndarray, found_h: np.ndarray, made_h: np.ndarray,
                    chance_h: np.ndarray) -> np.ndarray:
    """`estimators._half_is_period`, elementwise."""
    s0 = np.minimum(found / np.where(made > 0.0, made, 1.0), HALF_SHARE_CAP)
    llr = est._binomial_llr(found_h, made_h, s0, chance_h)
    return (made > 0.0) & (made_h > 0.0) & (found_h >= 1.0) & (llr > HALF_LLR)


def _event_half_rule(lags: np.ndarray, vote: np.ndarray, found_n: np.ndarray, valid_n: np.ndarray,
                     lag0: np.ndarray, fraction: float) -> np.ndarray:
    """`estimators._event_half_rule` of a group: a loop over halvings, vectorised over rows."""
    lag0 = lag0.copy()
    going = np.ones(lag0.size, bool)
    gi = np.arange(lag0.size)
    while True:
        going &= lag0 / 2.0 >= lags[0]
        sel = going[:, None] & (np.abs(lags[None, :] - (lag0 / 2.0)[:, None])
                                <= (TOL_SAMPLES + fraction * lag0 / 2.0)[:, None])
        going &= sel.any(axis=1)
        if not going.any():
            return lag0
        j = np.argmax(np.where(sel, vote, -np.inf), axis=1)
        fj, vj = found_n[gi, j], valid_n[gi, j]
        going &= ~((fj < SUBHARMONIC_MIN_FOUND) | (fj < SUBHARMONIC_SHARE * vj))
        c = np.argmin(np.abs(lags[None, :] - lag0[:, None]), axis=1)
        fc, vc = found_n[gi, c], valid_n[gi, c]
        vj_safe = np.where(going, vj, 1.0)
        pooled = (fc + fj) / np.maximum(vc + vj, 1.0)
        se = np.sqrt(np.maximum(pooled * (1.0 - pooled), 1e-12) * (1.0 / np.maximum(vc, 1.0) + 1.0 / vj_safe))
        going &= ~(fc / np.maximum(vc, 1.0) - fj / vj_safe > SUBHARMONIC_Z * se)
        lag0 = np.where(going, lags[j], lag0)


def _period(times: np.ndarray, pos: np.ndarray, drift: np.ndarray, lag0: np.ndarray, rate_hz: float, n_bins: int,
            fraction: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The tail of `estimators.periodicity` for a group: rate, rate std, score, phases, tolerance
    (in periods), period (series samples). After a search wider than TOL_FRACTION the lag is
    refined and matched again closely where that matches anything, as the reference; the score
    counts the search's pairs. Mean and std of the matched intervals run per match count (numpy's
    pairwise sums depend on the length); the scalar tail in Python floats, as the reference."""
    g, k = times.shape
    diff = times[:, None, :] - times[:, :, None]
    intervals, matched, mult = est._matched_intervals(diff, lag0[:, None, None], fraction)  # the score's pairs
    n_matched, mean, spread = _interval_stats(intervals, matched, lag0)
    if fraction > TOL_FRACTION:
        narrow_intervals, narrow, _ = est._matched_intervals(diff, mean[:, None, None], TOL_FRACTION)
        use = (n_matched > 0) & narrow.any(axis=(1, 2))
        lag0 = np.where(use, mean, lag0)
        kept = np.where(use[:, None, None], narrow, matched)
        n_matched, mean, spread = _interval_stats(np.where(use[:, None, None], narrow_intervals, intervals), kept,
                                                  lag0)
    rate, std, tol = np.empty(g), np.empty(g), np.empty(g)
    for b, (period, lag, scatter, count) in enumerate(zip(mean.tolist(), lag0.tolist(), spread.tolist(),
                                                         n_matched.tolist())):
        tol0 = TOL_SAMPLES + TOL_FRACTION * lag
        if count <= 1:
            scatter = tol0
        period_std = math.sqrt(scatter ** 2 + 1.0 / 12.0) / math.sqrt(max(count, 1))
        rate[b] = rate_hz / period
        std[b] = rate[b] * period_std / period
        tol[b] = tol0 / period
    phases = np.mod(times / mean[:, None], 1.0)
    moved = pos[:, None, :] - pos[:, :, None] - drift[:, None, None] * diff
    informative = (pos > 0.0) & (pos < n_bins - 1)
    same_place = (np.abs(moved) <= POSITION_TOL_BINS) | ~informative[:, None, :] | ~informative[:, :, None]
    score = (np.sum(matched & same_place & (mult == 1), axis=(1, 2))
             + SECOND_PERIOD_GAIN * np.sum(matched & same_place & (mult == 2), axis=(1, 2)))
    return rate, std, score.astype(float), phases, tol, mean


def _interval_stats(intervals: np.ndarray, matched: np.ndarray,
                    lag: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row: matched count, mean of the matched intervals (`lag` where none), their std (NaN
    below two), run per match count as the reference's 1-D means."""
    n_matched = matched.sum(axis=(1, 2))
    mean = lag.astype(np.float64).copy()
    spread = np.full(lag.shape[0], np.nan)
    for m in distinct(n_matched[n_matched > 0]):
        sel = np.flatnonzero(n_matched == m)
        vals = intervals[sel][matched[sel]].reshape(sel.size, m)
        mean[sel] = vals.mean(axis=1)
        if m > 1:
            spread[sel] = vals.std(axis=1)
    return n_matched, mean, spread


def _rotor_count(phases: np.ndarray, tol: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`estimators.rotor_count` of rows of k >= 2 phases: circular groups split at gaps > tol."""
    ph = np.sort(phases, axis=1)
    gaps = np.diff(np.concatenate([ph, ph[:, :1] + 1.0], axis=1), axis=1)
    breaks = gaps > np.maximum(tol, 1e-3)[:, None]
    groups = breaks.sum(axis=1)
    singletons = (breaks & np.roll(breaks, -1, axis=1)).sum(axis=1)
    return np.where(groups > 0, groups, 1).astype(float), np.where(groups > 0, 0.5 * singletons, 0.0)


# --- long dwells: the flash rate from the envelope's spectrum --------------------------------

@dataclass(frozen=True)
class FlashTrain:
    """What the envelope of a long dwell gives per row (B,): see `spectral_flash_rate`."""

    rate_hz: np.ndarray
    rate_std_hz: np.ndarray
    score: np.ndarray
    rotors_seen: np.ndarray  # rotors visible: a lower bound (`signatures.rotor_lines`)
    rotors_seen_std: np.ndarray
    rotors_known: np.ndarray | None = None  # bool: False where the fold gives no count (`count_known`)


def flash_envelope(slow: np.ndarray, config: RadarConfig, body_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sum, difference) of the approaching and receding halves' power envelopes of each row of
    long-dwell gates `slow` (B, pulses, bins), each (B, pulses): demodulated by the body Doppler,
    its ends tapered (`ENVELOPE_TAPER`), the body's and the clutter's line dropped
    (`line_width_hz`; `spectral_flash_rate` says why the sum and the difference). Moving clutter
    at +40 dB spreads over tens of Hz at S-band, and a fixed band let it into the envelope as a
    slow wander. A flying body's clutter line lies at minus its Doppler here, apart from the
    body's: it is dropped too, as far as it reaches in the radar's frame; swaying clutter 20-40 dB
    over the flashes buried their train there (`authn features accuracy --condition
    cw-moving-tagged`)."""
    n = slow.shape[1]
    t = np.arange(n)
    demod = np.exp((-2j * math.pi * body_hz * config.pri_s)[:, None] * t)
    x = (slow * demod[:, :, None]).astype(np.complex64)
    spec = np.fft.fft((x - x.mean(axis=1, keepdims=True)) * tukey(n, ENVELOPE_TAPER)[None, :, None], axis=1)
    f = np.fft.fftfreq(n, d=config.pri_s)
    power = (spec.real ** 2 + spec.imag ** 2).sum(axis=2)
    width = line_width_hz(power, config.pri_s)
    keep = np.abs(f)[None, :] > width[:, None]
    prf = 1.0 / config.pri_s
    body = (np.asarray(body_hz, dtype=np.float64) + prf / 2) % prf - prf / 2  # aliased into +-PRF / 2
    apart = np.flatnonzero(np.abs(body) > width)
    if apart.size:  # the radar's frame: bin j there is bin j - body / df here
        shift = np.rint(body[apart] * n * config.pri_s).astype(int)
        radar = power[apart[:, None], (np.arange(n)[None, :] - shift[:, None]) % n]
        reach = line_width_hz(radar, config.pri_s)
        keep[apart] &= np.abs((f[None, :] + body[apart, None] + prf / 2) % prf - prf / 2) > reach[:, None]
    halves = []
    for half in (f > 0, f < 0):
        part = np.fft.ifft(spec * (keep & half[None, :])[:, :, None], axis=1)
        halves.append((part.real ** 2 + part.imag ** 2).sum(axis=2))
    return halves[0] + halves[1], halves[0] - halves[1]


def taper_length(n: int, share: float) -> int:
    """Points tapered at each end of n by a Tukey window over `share` of them (`tukey`)."""
    return int(share * (n - 1) / 2.0)


def tukey(n: int, share: float) -> np.ndarray:
    """A Tukey window of n points (float32): cosine tapers over `share` of them, half at each end,
    1 between (numpy only: the check path does not import scipy)."""
    w = np.ones(n, dtype=np.float32)
    edge = taper_length(n, share)
    if edge >= 1:
        ramp = 0.5 * (1.0 - np.cos(np.pi * np.arange(edge) / edge))
        w[:edge] = ramp
        w[n - edge:] = ramp[::-1]
    return w


def line_width_hz(power: np.ndarray, pri_s: float) -> np.ndarray:
    """Per row of Doppler power spectra (B, pulses) in FFT order: how far (Hz) either side of zero
    the line there reaches. The power of both sides at each |f|, smoothed over SPECTRAL_SMOOTH_HZ,
    is followed out from SPECTRAL_BODY_HZ to where it falls to CLUTTER_FLOOR_FACTOR times its
    median beyond SPECTRAL_BODY_HZ (the micro-Doppler's floor), at most an eighth of the PRF;
    SPECTRAL_BODY_HZ at least."""
    n = power.shape[1]
    df = 1.0 / (n * pri_s)
    m = (n - 1) // 2
    folded = power[:, : n // 2 + 1].astype(np.float64)
    folded[:, 1:1 + m] += power[:, n - 1:n - 1 - m:-1]  # -f onto +f
    k = max(1, int(round(SPECTRAL_SMOOTH_HZ / df)))
    c = np.concatenate([np.zeros((folded.shape[0], 1)), np.cumsum(folded, axis=1)], axis=1)
    lo_i = np.clip(np.arange(folded.shape[1]) - k // 2, 0, folded.shape[1])
    hi_i = np.clip(lo_i + k, 0, folded.shape[1])
    smooth = (c[:, hi_i] - c[:, lo_i]) / np.maximum(hi_i - lo_i, 1)
    lo = min(int(math.ceil(SPECTRAL_BODY_HZ / df)), folded.shape[1] - 1)
    hi = max(lo + 1, min(folded.shape[1], n // 8))
    floor = median_last(smooth[:, lo:])
    under = smooth[:, lo:hi] <= CLUTTER_FLOOR_FACTOR * floor[:, None]
    first = np.where(under.any(axis=1), np.argmax(under, axis=1), hi - lo) + lo  # the first bin past the line
    return np.maximum((first - 1) * df, SPECTRAL_BODY_HZ)


def spectral_flash_rate(slow: np.ndarray, config: RadarConfig, body_hz: np.ndarray) -> FlashTrain:
    """The flash train of each row of long-dwell gates `slow` (B, pulses, bins): its rate (Hz),
    std and score, and the rotors visible (`signatures.rotor_lines.visible_rotors`: a lower bound).

    Why: a dwell of SPECTRAL_DWELL_S or more holds hundreds of flashes, and the period search
    keeps only its strongest events; the flash train's envelope spectrum instead resolves the
    rate to PRF / pulses (1.2 Hz in a 0.82 s dwell) and its peak is refined below a bin.
    How: demodulate by the body Doppler, drop the body's +-SPECTRAL_BODY_HZ and split the rest
    into its approaching and receding halves. A two-blade rotor's blades face the radar together,
    one approaching and one receding, so the sum of the halves' power envelopes flashes at the
    flash rate F = 2 f_rot whether the blades are equal or not; their difference is periodic
    only where one blade reflects more (a tagged blade), and then once a turn, at F / 2.
    The sum's spectrum, whitened (`_whitened`: sway and clutter wander rise towards 0 Hz), is
    summed at SPECTRAL_HARMONICS multiples of each candidate in [FLASH_RATE_MIN_HZ,
    FLASH_RATE_MAX_HZ] that shows a line of its own (a train of short flashes has its
    fundamental: a candidate without one is a multiple or a fraction of the train whose
    harmonics happen to line up, 3/2 or 5/4 of it), the best divided by 3 while its third and
    two thirds show lines, and halved while half of it shows the first and third harmonics, or
    while a third or a half of it holds a stronger line than the best's own and the difference
    none (then the best was the train's third or second harmonic: four rotors' flashes at random
    phases can all but cancel a train's fundamental, never make one stronger than it; a line in
    the difference there may be a tagged rotor's turn, which the rules below read). Where the best candidate
    is the difference's stronger line of the candidate and its half, the difference holds at
    least the sum's power there, and it is a turn line (`_turn_line`) or the difference holds
    under ONE_SIDED_SHARE of the sum at twice the candidate, it is a tagged rotor's turn rate,
    not its flash rate, and the rate is doubled: a turn alternates sides, so the difference
    carries it at full strength and cancels the flash train's own line, while equal blades seen
    in one half only hold as much in the difference as in the sum at every line. Conversely a
    rate whose half or third turns at its own half (`_turned`) was a harmonic of a tagged
    train: divided. Last, a best whose harmonics off its second (or third) are ten times under
    that one's line, with no turn in the difference, is a sub-harmonic: multiplied.
    The peak is refined by a parabola through the log harmonic sum; its std is the sub-bin
    peak's half width over sqrt(harmonics). Score: log of the peak over the median of the
    harmonic sum, less SPECTRAL_NOISE_LOG (as the period search's score, >= 1 is a periodic
    train)."""
    b_rows, n = slow.shape[0], slow.shape[1]
    total, diff = flash_envelope(slow, config, body_hz)
    sum_power = np.abs(np.fft.rfft(total - total.mean(axis=1, keepdims=True), axis=1)) ** 2
    diff_power = np.abs(np.fft.rfft(diff - diff.mean(axis=1, keepdims=True), axis=1)) ** 2
    power, asym = _whitened(sum_power), _whitened(diff_power)
    df = config.prf_hz / n
    lo = max(1, int(math.ceil(FLASH_RATE_MIN_HZ / df)))
    hi = min(power.shape[1] - 1, int(FLASH_RATE_MAX_HZ / df))
    if hi <= lo + 2:
        zero = np.zeros(b_rows)
        return FlashTrain(zero, zero, zero, zero, zero)
    cand = np.arange(lo, hi + 1)
    harm = np.zeros((b_rows, cand.size))
    width = power.shape[1]
    own = np.max(np.stack([power[:, np.clip(cand + d, 0, width - 1)] for d in (-1, 0, 1)]), axis=0)
    for k in range(1, SPECTRAL_HARMONICS + 1):  # harmonic k of a candidate lies within k / 2 bins of k c
        reach = k // 2
        idx = cand * k
        ok = idx + reach < width
        near = np.max(np.stack([power[:, idx[ok] + d] for d in range(-reach, reach + 1)]), axis=0)
        harm[:, ok] += np.minimum(near, HARMONIC_CAP * own[:, ok])
    fundamental = np.where(own > SPECTRAL_TAG_LINE, harm, 0.0)  # candidates with a line of their own
    best = np.argmax(np.where(fundamental.max(axis=1, keepdims=True) > 0.0, fundamental, harm), axis=1)
    rows = np.arange(b_rows)
    best = _octave_corrected(best, cand, lo, hi, power, sum_power, asym)
    inner = (best > 0) & (best < cand.size - 1)
    bi = np.clip(best, 1, cand.size - 2)
    a, m, c = (np.log(np.maximum(harm[rows, bi + j], 1e-300)) for j in (-1, 0, 1))
    den = a - 2.0 * m + c
    with np.errstate(divide="ignore", invalid="ignore"):
        step = np.where(inner & (den < 0.0), np.clip(0.5 * (a - c) / np.where(den < 0, den, -1.0), -0.5, 0.5), 0.0)
    rate = (cand[best] + step) * df
    turn = ((_line(asym, rate / df) > np.maximum(_line(asym, rate / df / 2.0), SPECTRAL_TAG_LINE))
            & (_line(diff_power, rate / df) >= _line(sum_power, rate / df))
            & (_turn_line(rate / df, asym, diff_power, sum_power) | ~_one_sided(rate / df, diff_power, sum_power)))
    rate = np.where(turn, 2.0 * rate, rate)
    rate = _turned(rate / df, asym, diff_power, sum_power, lo) * df
    med = median_last(harm)
    score = np.maximum(np.log(np.maximum(harm[rows, best], 1e-300) / np.maximum(med, 1e-300))
                       - SPECTRAL_NOISE_LOG, 0.0)
    live = harm[rows, best] > 0.0
    rate = np.where(live, rate, 0.0)
    std = np.where(live, np.where(turn, 2.0, 1.0) * 0.5 * df / math.sqrt(SPECTRAL_HARMONICS), 0.0)
    edge = taper_length(n, ENVELOPE_TAPER)  # the rotors are counted where the envelope is not tapered
    known = np.array([count_known(n - 2 * edge, rate[b] * config.pri_s) for b in range(b_rows)], dtype=bool)
    seen = np.array([float(len(visible_rotors(total[b, edge:n - edge], rate[b] * config.pri_s))) if known[b] else 0.0
                     for b in range(b_rows)])
    return FlashTrain(rate, std, np.where(live, score, 0.0), seen, np.where(seen > 0.0, VISIBLE_STD, 0.0),
                      known | ~live)


def _octave_corrected(best: np.ndarray, cand: np.ndarray, lo: int, hi: int, power: np.ndarray,
                      sum_power: np.ndarray, asym: np.ndarray) -> np.ndarray:
    """The best candidate (index into `cand`, bins `lo`..`hi`) of each row moved to the train's
    fundamental where it was a harmonic of it (lines under it that a train's fundamental makes), or
    up to the harmonic where it was a sub-harmonic (its own harmonics off that one the sampling's);
    `spectral_flash_rate` says why."""
    for _ in range(2):  # the lines a train's fundamental would make under the best: it was a harmonic
        for order, under in SUBHARMONIC_LINES:
            base = cand[best] / order
            # a train's fundamental is about its strongest line (a single-peaked flash's harmonics
            # fall off): lines under the best but far weaker than it are the sampling's, not a train's
            # (compared in power, not whitened: the whitening floor under a strong line is raised by
            # its own skirt, so a line 500x weaker than it whitened to a tenth of it)
            own = _line(sum_power, cand[best].astype(float))
            shown = ((np.all([_line(power, j * base) > SPECTRAL_TAG_LINE for j in under], axis=0)
                      & (_line(sum_power, base) * SPECTRAL_TAG_LINE >= own))
                     | ((_line(sum_power, base) > own) & (_line(power, base) > SPECTRAL_TAG_LINE)  # over its harmonic
                        & (_line(asym, base) <= SPECTRAL_TAG_LINE)))  # ... unless a tagged rotor's turn
            best = np.where(shown & (base >= lo), np.clip(np.rint(base).astype(int) - lo, 0, cand.size - 1), best)
    for order in (2, 3):  # the converse: a best whose own harmonics off the order-th are the sampling's
        up = cand[best] * order
        off = np.max([_line(sum_power, k * cand[best].astype(float)) for k in range(1, SPECTRAL_HARMONICS + 1)
                      if k % order], axis=0)  # in power, as above
        shown = ((_line(sum_power, up.astype(float)) > SPECTRAL_TAG_LINE * off)
                 & (_line(power, up.astype(float)) > SPECTRAL_TAG_LINE)
                 & (_line(asym, cand[best].astype(float)) <= SPECTRAL_TAG_LINE))
        best = np.where(shown & (up <= hi), np.clip(up - lo, 0, cand.size - 1), best)
    return best


def _turn_line(at: np.ndarray, asym: np.ndarray, diff_power: np.ndarray, sum_power: np.ndarray) -> np.ndarray:
    """Whether each row's envelope difference shows a tagged rotor's turn at fractional bin `at`: a
    line of its own (SPECTRAL_TAG_LINE over the whitened floor) holding TURN_SHARE^-1 times the
    sum's power there or more (a turn alternates sides, so the sum cancels it: a flash train seen
    in one half only, or leaking into the difference, holds as much in the sum)."""
    return ((_line(asym, at) > SPECTRAL_TAG_LINE)
            & (_line(diff_power, at) * TURN_SHARE >= _line(sum_power, at)))


def _one_sided(at: np.ndarray, diff_power: np.ndarray, sum_power: np.ndarray) -> np.ndarray:
    """Whether each row's envelope difference holds ONE_SIDED_SHARE of the sum's power or more at
    twice fractional bin `at`: a flash train seen in one half only, where a turn at `at` would have
    cancelled there."""
    return _line(diff_power, 2.0 * at) >= ONE_SIDED_SHARE * _line(sum_power, 2.0 * at)


def _turned(rate: np.ndarray, asym: np.ndarray, diff_power: np.ndarray, sum_power: np.ndarray,
            lo: int) -> np.ndarray:
    """Flash rates (fractional bins) divided by m (TURN_MULTIPLES, the largest that holds) where the
    difference shows a turn at half the m-th part: a tagged rotor turns once per two flashes, so a
    rate a part of which turns at its half was a harmonic of the train (its fundamental weak where
    four rotors' flashes interfere), and the turn's own third harmonic lies at half of 3 F. The turn
    must hold a SPECTRAL_TAG_LINE-th of the rate's own line or more (lines far weaker than a train's
    are not its turn), and where the rate's half is a turn line itself, 1 / TURN_SHARE times its
    power (else the rate turns at its half, and the part's line is a leak or a harmonic)."""
    train = _line(sum_power, rate)
    has_turn = _turn_line(rate / 2.0, asym, diff_power, sum_power)
    own_turn = _line(diff_power, rate / 2.0)
    out = rate.copy()
    for m in TURN_MULTIPLES:  # the largest part wins: a turn's own odd harmonics are turn lines too
        part = rate / m
        turn = _line(diff_power, part / 2.0)
        found = ((part >= lo) & _turn_line(part / 2.0, asym, diff_power, sum_power)
                 & (turn * SPECTRAL_TAG_LINE >= train) & (~has_turn | (turn * TURN_SHARE >= own_turn)))
        out = np.where(found, part, out)
    return out


def _line(power: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Each row's whitened power at fractional bin `at[row]`: the larger of its two nearest bins."""
    k = np.clip(np.floor(at).astype(int), 0, power.shape[1] - 2)
    rows = np.arange(power.shape[0])
    return np.maximum(power[rows, k], power[rows, k + 1])


def _whitened(power: np.ndarray) -> np.ndarray:
    """Each row of an envelope power spectrum over its local floor: the median of blocks of
    SPECTRAL_FLOOR_BINS bins, interpolated between block centres (flash lines are a few bins
    wide, so a block's median is its floor)."""
    rows, m = power.shape
    block = min(SPECTRAL_FLOOR_BINS, m)
    n_blocks = max(1, m // block)
    floor = median_last(power[:, :n_blocks * block].reshape(rows, n_blocks, block))
    centres = (np.arange(n_blocks) + 0.5) * block
    x = np.arange(m)
    level = np.stack([np.interp(x, centres, f) for f in floor])
    return power / np.maximum(level, 1e-300)
