"""The single-return blade-flash estimators: the reference the array-first ones
(`signatures.dsp.flash_series`, `signatures.dsp.flash_period`) are tested against row by row, to the bit
(tests/features/test_batch_estimators.py).

Not product code: the product runs the array-first modules only (one return is a batch of one);
this is the straightforward per-return form of the same algorithm (docs in those modules), kept
so that a change to the vectorised bookkeeping that alters any row is caught. It shares the
product's constants and primitives (matched filters, window sums, binomial LLR), not its
bookkeeping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signatures.dsp.flash_period import (COHERENT_LEVEL, COHERENT_SHARE, EVENT_TOL_FRACTION, FULL_VOTE_DB,
                                         GROUP_GAP_PERIODS, GROUP_GAP_SAMPLES, HALF_LLR, HALF_SHARE_CAP, MIN_OVERLAP,
                                         MIN_VOTE_WEIGHT, POSITION_TOL_BINS, RERANK_N, RERANK_WEIGHT,
                                         SECOND_PERIOD_GAIN, SKIRT_DB, SKIRT_REACH, SUBHARMONIC_MIN_FOUND,
                                         SUBHARMONIC_SHARE, SUBHARMONIC_Z, TOL_FRACTION, TOL_SAMPLES, binomial_llr,
                                         matched_intervals, peak_positions)
from signatures.dsp.flash_series import (EVENT_RADIUS, FLASH_RATE_MAX_HZ, FLASH_RATE_MIN_HZ, NOISE_MADS, SERIES_RATE_HZ,
                                         FlashSeriesBatch, clutter_pass, flashes_within_one_sample, highpass_s,
                                         matched_filters, window_sums)
from signatures.radar import RadarConfig
from signatures.dsp.stats import median


@dataclass(frozen=True)
class Estimate:
    """A value with a one-sigma uncertainty (both finite; value 0 and std 0 when absent)."""

    value: float
    std: float


@dataclass(frozen=True)
class FlashSeries:
    """One return's flash series (`flash_series`; `FlashSeriesBatch` holds B of them)."""

    energy: np.ndarray  # float64 (n,), flash energy above the noise, >= 0
    per_bin: np.ndarray  # float64 (n, bins): the energy before the noise cut, per range bin
    rate_hz: float  # sample rate of the series
    radius: int  # samples either side a flash can spread over
    drift_bins_per_sample: float  # body range migration (bins per series sample)
    threshold: float = 0.0  # detection level subtracted from the energy (median + NOISE_MADS MAD)
    field: np.ndarray | None = None  # complex (chirps, positions): matched-filter outputs of the
    # high-passed, body-demodulated bins (noise: unit variance per position)
    decimation: int = 1  # chirps per series sample


def series_row(batch: FlashSeriesBatch, b: int) -> FlashSeries:
    """Row b of a batch as the single-return series (what `flash_series` gives for that return)."""
    return FlashSeries(batch.energy[b], batch.per_bin[b], batch.rate_hz, batch.radius,
                       float(batch.drift_bins_per_sample[b]), float(batch.threshold[b]),
                       None if batch.field is None else batch.field[b].T, batch.decimation)


def flash_series(slow: np.ndarray, config: RadarConfig, body_hz: float,
                 range_bin_m: float, n_fft: int) -> FlashSeries:
    """Matched-filter energy of the fast-varying part of the target bins per (decimated) chirp.

    `slow` is (chirps x bins): adjacent bins of a Hann-windowed `n_fft`-point range
    FFT, not windowed in slow time; or (chirps x windows x bins) from sub-chirp windows of
    `n_fft` points (`subchirp_bins`), each chirp then taking its best window's values. The
    energy is the best position's (summed over a decimation block); the series is that
    energy above a robust noise level (median + NOISE_MADS MAD), clipped at 0.
    """
    n = slow.shape[0]
    windows = slow.shape[1] if slow.ndim == 3 else 1
    n_bins = slow.shape[-1]
    t = np.arange(n)
    demod = np.exp(-2j * math.pi * body_hz * config.pri_s * t).astype(np.complex64)
    z0 = slow.reshape(n, windows * n_bins) * demod[:, None]
    length = max(3, int(round(highpass_s(config.wavelength_m) / config.pri_s)) | 1)
    if n > length:
        # the moving average in the body's frame (body, hubs), then in the radar's (clutter;
        # `clutter_pass`); two passes: the second moving averages leave out the flashes the first
        # found (+-1 chirp), so a strong flash leaves no -19 dB echo around itself
        clutter = bool(clutter_pass(np.array([body_hz]), config.pri_s, length)[0])
        z = _highpass(z0, length)
        if clutter:
            z = _highpass(z * demod.conj()[:, None], length) * demod[:, None]
        e1 = (z.real ** 2 + z.imag ** 2).sum(axis=1)
        strong = e1 > _noise_level(e1)
        strong[1:] |= strong[:-1].copy()
        strong[:-1] |= strong[1:].copy()
        z = _highpass(z0, length, ~strong)
        if clutter:
            z = _highpass(z * demod.conj()[:, None], length, ~strong) * demod[:, None]
    else:
        z = z0 - z0.mean(axis=0, keepdims=True)
    filters = matched_filters(n_bins, n_fft).conj().astype(z.dtype)
    if slow.ndim == 3:  # each chirp: the window whose best position holds the most energy
        z3 = z.reshape(n, windows, n_bins)
        y3 = (z.reshape(n * windows, n_bins) @ filters).reshape(n, windows, -1)  # one product, not n
        pick = np.argmax((y3.real ** 2 + y3.imag ** 2).max(axis=2), axis=1)
        z, y = z3[t, pick], y3[t, pick]
    else:
        y = z @ filters  # (chirps, positions)
    eb = (z.real ** 2 + z.imag ** 2).astype(np.float64)
    ey = (y.real ** 2 + y.imag ** 2).astype(np.float64)
    dec = max(1, int(config.prf_hz // SERIES_RATE_HZ))
    m = (n // dec) * dec
    if m >= dec:
        eb = eb[:m].reshape(-1, dec, eb.shape[1]).sum(axis=1)
        ey = ey[:m].reshape(-1, dec, ey.shape[1]).sum(axis=1)
    e = ey.max(axis=1)
    level = _noise_level(e)
    above = np.maximum(e - level, 0.0)
    drift = body_hz * config.wavelength_m / 2.0 * config.pri_s * dec / range_bin_m
    keep = flashes_within_one_sample(config.prf_hz / dec, dec, config.wavelength_m)  # the coherent checks' premise
    return FlashSeries(above, eb, config.prf_hz / dec, EVENT_RADIUS, drift, level, y if keep else None, dec)


def _noise_level(e: np.ndarray) -> float:
    med = float(median(e))
    return med + NOISE_MADS * 1.4826 * float(median(np.abs(e - med)))


def _highpass(z: np.ndarray, length: int, keep: np.ndarray | None = None) -> np.ndarray:
    """z minus its moving average over `length` chirps of the samples with keep = True; where
    fewer than half the window is kept, the average runs over a 4x longer window."""
    n = z.shape[0]
    t = np.arange(n)
    half = length // 2
    zk = z if keep is None else np.where(keep[:, None], z, 0)
    sums = window_sums(zk, half)
    lo, hi = np.maximum(t - half, 0), np.minimum(t + half + 1, n)
    if keep is None:
        return z - sums / (hi - lo)[:, None].astype(np.float32)
    ck = np.concatenate([[0], np.cumsum(keep)])
    cnt = ck[hi] - ck[lo]
    thin = cnt < max(2, length // 2)
    if thin.any():
        lo2, hi2 = np.maximum(t - 2 * length, 0), np.minimum(t + 2 * length + 1, n)
        sums = np.where(thin[:, None], window_sums(zk, 2 * length), sums)
        cnt = np.where(thin, ck[hi2] - ck[lo2], cnt)
    return z - sums / np.maximum(cnt, 1)[:, None].astype(np.float32)


@dataclass(frozen=True)
class Periodicity:
    """Blade-flash periodicity of a flash series."""

    flash_rate: Estimate  # Hz
    score: float  # matched flash pairs at the chosen period (0 = no periodicity)
    n_events: int  # flashes found in the dwell
    phases: np.ndarray  # flash times modulo the period, in periods [0, 1)
    tolerance: float  # matching tolerance in periods
    flash_par_db: float  # peak-to-average power ratio of the flash series (impulsiveness)
    rotors_seen: Estimate = Estimate(0.0, 0.0)  # distinct flashes per flash period (`rotors_seen`)


def flash_events(series: FlashSeries, radius: int,
                 max_events: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Flash times (series samples, sub-sample centroid) and range positions (bins).

    Times: local maxima within +-radius of the energy above the noise that rise
    above the sinc skirt of every stronger event within SKIRT_REACH samples
    (SKIRT_DB - 20 log10 distance, relative to it), strongest first up to
    `max_events`, then sorted. Position: log-parabolic peak of the flash's energy
    over the gate's range bins (a broadside blade sits at its hub's range).
    """
    e = series.energy
    if e.size == 0 or float(e.max()) <= 0.0:
        return np.zeros(0), np.zeros(0)
    pad = np.concatenate([np.zeros(radius), e, np.zeros(radius)])
    windows = np.lib.stride_tricks.sliding_window_view(pad, 2 * radius + 1)
    peaks = np.flatnonzero((e > 0.0) & (e >= windows.max(axis=1)))
    peaks = peaks[np.argsort(-e[peaks], kind="stable")]
    raw = e + series.threshold
    skirt = 10.0 ** (SKIRT_DB / 10.0)
    kept: list[int] = []
    for p in peaks.tolist():
        if all(abs(p - q) > SKIRT_REACH or raw[p] >= raw[q] * skirt / (p - q) ** 2 for q in kept):
            kept.append(p)
            if len(kept) >= max_events:
                break
    peaks = np.array(kept, dtype=int)
    lo, hi = np.maximum(peaks - 1, 0), np.minimum(peaks + 1, e.size - 1)
    w = e[lo] + e[peaks] + e[hi]
    centroid = (lo * e[lo] + peaks * e[peaks] + hi * e[hi]) / np.maximum(w, 1e-300)
    positions = peak_positions(series.per_bin[peaks])
    order = np.argsort(centroid)
    return centroid[order], positions[order]


def _votes(times: np.ndarray, pos: np.ndarray, weight: np.ndarray, lags: np.ndarray, n: int,
           drift: float, n_bins: int, fraction: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per lag: log-likelihood ratio, partners found, partner checks made (see `periodicity`),
    partners within TOL_SAMPLES + fraction x lag."""
    k = times.size
    informative = (pos > 0.0) & (pos < n_bins - 1)  # a peak at the gate's edge has no position
    moved = pos[None, :] - pos[:, None] - drift * (times[None, :] - times[:, None])
    compat = (np.abs(moved) <= POSITION_TOL_BINS) | ~informative[None, :] | ~informative[:, None]
    share_compat = (compat.sum() - k) / max(k * (k - 1), 1)
    tol = (TOL_SAMPLES + fraction * lags)[None, :, None]
    target = times[None, None, :] + np.array([1.0, -1.0])[:, None, None] * lags[None, :, None]
    valid = (target >= tol) & (target <= n - 1 - tol)  # (2 signs, lags, events)
    idx = np.searchsorted(times, target)
    flat = compat.ravel()
    own = np.arange(k) * k
    found = np.zeros(target.shape, bool)
    for cand in (np.minimum(idx, k - 1), np.maximum(idx - 1, 0)):
        found |= (np.abs(times[cand] - target) <= tol) & flat[own + cand]
    found &= valid
    found_w = (found @ weight).sum(axis=0)
    valid_w = (valid @ weight).sum(axis=0)
    found_n = found.sum(axis=(0, 2)).astype(float)
    valid_n = valid.sum(axis=(0, 2)).astype(float)
    tol = tol[0, :, 0]
    chance = np.minimum(np.maximum(1.0 - np.exp(-(k - 1) / n * 2.0 * tol * share_compat), 1e-3), 0.999)
    share = np.minimum(np.maximum(found_w / np.maximum(valid_w, 1e-12), 1e-9), 1.0 - 1e-9)
    llr = found_w * np.log(share / chance) + (valid_w - found_w) * np.log((1.0 - share) / (1.0 - chance))
    # x share: at the true period all rotors' checks succeed, at an inter-rotor lag only some
    return np.where(share > chance, llr * share, 0.0), found_n, valid_n


@dataclass(frozen=True)
class _Coherent:
    """Coherent partner hits of each event (see `_coherent`)."""

    counts: np.ndarray  # (k, n + 1) cumulative count of hits along the series, per event
    share: float  # share of series samples (away from the events themselves) that hit


def _coherent(series: FlashSeries, times: np.ndarray) -> _Coherent | None:
    """Per event and series sample: is there a flash at the event's range position and with
    its carrier phase (up to a sign)? The matched-filter output at the event's best position,
    real part relative to the event's phase only (in phase), squared, above COHERENT_LEVEL x
    its median-based noise level and holding at least COHERENT_SHARE of the best position's
    energy at that chirp (best chirp of a decimation block). None where the field is missing
    or the PRI is shorter than a flash lobe."""
    n = series.energy.size
    dec = max(1, series.decimation)
    if times.size == 0 or not _coherent_applies(series):
        return None
    field = series.field[:n * dec]
    ti = np.minimum(np.maximum(np.rint(times).astype(int), 0), n - 1)
    rows = ti * dec
    if dec > 1:
        block = field.reshape(n, dec, -1)[rows // dec]
        rows = rows + np.argmax((block.real ** 2 + block.imag ** 2).sum(axis=2), axis=1)
    energy = field.real ** 2 + field.imag ** 2  # (n * dec, positions)
    at = np.argmax(energy[rows], axis=1)  # each event's best position
    own = field[rows, at]
    phase = own / np.maximum(np.abs(own), 1e-30)
    power = np.square((field[:, at] * phase.conj()[None, :]).real.T)  # (k, n * dec)
    total = energy.max(axis=1)  # (n * dec,)
    coherent = power >= np.float32(COHERENT_SHARE) * total[None, :]
    if dec > 1:
        coherent = coherent.reshape(-1, n, dec)
        power = power.reshape(-1, n, dec)
        pick = np.argmax(np.where(coherent, power, np.float32(-1.0)), axis=2)[..., None]
        coherent = np.take_along_axis(coherent, pick, axis=2)[..., 0]
        power = np.take_along_axis(power, pick, axis=2)[..., 0]
    half = n // 2
    median = np.partition(power, half, axis=1)[:, half:half + 1]
    # chi-square with 1 degree of freedom: median = 0.455 x mean
    hit = coherent & (power > np.float32(COHERENT_LEVEL / 0.455) * np.maximum(median, np.float32(1e-30)))
    counts = np.zeros((times.size, n + 1), np.int32)
    np.cumsum(hit, axis=1, out=counts[:, 1:])
    ev = np.arange(times.size)
    lo, hi = np.maximum(ti - 2, 0), np.minimum(ti + 3, n)
    own_hits = float((counts[ev, hi] - counts[ev, lo]).sum())  # each event's own flash +-2
    others = max(float(times.size * n - (hi - lo).sum()), 1.0)
    return _Coherent(counts, max(float(counts[:, -1].sum()) - own_hits, 0.0) / others)


def _coherent_applies(series: FlashSeries) -> bool:
    """Does the series carry the complex field the coherent checks need, with flashes within
    one PRI?"""
    dec = max(1, series.decimation)
    return series.field is not None and series.field.shape[0] >= series.energy.size * dec


def _coherent_checks(coh: _Coherent, times: np.ndarray, weight: np.ndarray, lags: np.ndarray,
                     n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coherent partner checks at +-lag, per lag: (weighted found, weighted made, chance).

    A check is an event whose window t +- lag (TOL_SAMPLES + TOL_FRACTION lag) lies inside
    the dwell; it succeeds when the window holds a coherent hit. The chance of a hit is the
    series' hit share over the window.
    """
    tol = TOL_SAMPLES + TOL_FRACTION * lags  # (m,)
    w = np.floor(tol + 0.5).astype(int)
    chance = np.minimum(np.maximum(1.0 - (1.0 - coh.share) ** (2 * w + 1), 1e-3), 0.999)
    target = times[None, None, :] + np.array([1.0, -1.0])[:, None, None] * lags[None, :, None]
    t3, w3 = tol[None, :, None], w[None, :, None]
    ok = (target >= t3) & (target <= n - 1 - t3)
    centre = np.rint(target).astype(int)
    lo = np.minimum(np.maximum(centre - w3, 0), n)
    hi = np.minimum(np.maximum(centre + w3 + 1, 0), n)
    ev = np.arange(times.size)[None, None, :]
    hit = ok & (coh.counts[ev, hi] > coh.counts[ev, lo])
    return (hit @ weight).sum(axis=0), (ok @ weight).sum(axis=0), chance


def _rerank(coh: _Coherent, times: np.ndarray, weight: np.ndarray, lags: np.ndarray,
            vote: np.ndarray, lag0: float, n: int) -> tuple[float, bool]:
    """Re-ranked lag and whether its half is the period.

    Candidates: the RERANK_N strongest lags of the vote, each farther than the tolerance
    from the stronger ones (the vote's own best at its plateau centre lag0). Each is scored
    vote + RERANK_WEIGHT x share x coherent LLR over its checks at +-L and +-2L (a period
    predicts partners at its multiples). The winner's half replaces it when its coherent
    checks succeed about as often as the winner's own (`_half_is_period`).
    """
    positive = np.flatnonzero(vote > 0.0)
    left, at = vote[positive], lags[positive]
    reach = TOL_SAMPLES + TOL_FRACTION * at
    cands: list[float] = []
    scores: list[float] = []
    while len(cands) < RERANK_N and left.size:  # greedy: strongest lag away from the chosen
        j = int(np.argmax(left))
        if left[j] <= 0.0:
            break
        cands.append(lag0 if not cands else float(at[j]))
        scores.append(float(left[j]))
        left = np.where(np.abs(at - at[j]) <= reach, -np.inf, left)
    if not cands:
        return lag0, False
    c = len(cands)
    cl = np.array(cands)
    found, made, chance = _coherent_checks(coh, times, weight, np.concatenate([cl, 2.0 * cl, cl / 2.0]), n)
    share = (found[:c] + found[c:2 * c]) / np.maximum(made[:c] + made[c:2 * c], 1e-12)
    llr = (binomial_llr(found[:c], made[:c], share, chance[:c])
           + binomial_llr(found[c:2 * c], made[c:2 * c], share, chance[c:2 * c]))
    best = int(np.argmax(np.array(scores) + RERANK_WEIGHT * share * llr))
    half = bool(cands[best] / 2.0 >= lags[0] and _half_is_period(
        found[best], made[best], found[2 * c + best], made[2 * c + best], chance[2 * c + best]))
    return cands[best], half


def _half_is_period(found: float, made: float, found_h: float, made_h: float, chance_h: float) -> bool:
    """Do the coherent checks at lag/2 (found_h of made_h, chance_h each) succeed about as often
    as at lag (found of made): binomial LLR of the lag's share (capped at HALF_SHARE_CAP)
    against chance above HALF_LLR? A true half period repeats as reliably as twice it;
    another rotor half a period away mostly fails the phase and profile test."""
    if made <= 0.0 or made_h <= 0.0 or found_h < 1.0:
        return False
    s0 = min(found / made, HALF_SHARE_CAP)
    llr = binomial_llr(np.array([found_h]), np.array([made_h]), np.array([s0]), np.array([chance_h]))
    return bool(llr[0] > HALF_LLR)


def periodicity(series: FlashSeries) -> Periodicity:
    """Flash period from flash events (module docstring).

    Each event checks for a partner event within +-(TOL_SAMPLES + f L) of t - L and
    of t + L (f: TOL_FRACTION, or EVENT_TOL_FRACTION where no coherent checks apply),
    where that window lies inside the dwell; a partner counts when its range position
    agrees (POSITION_TOL_BINS after the body's migration; positions at the gate's edge
    agree with any). With checks weighted
    by the event's strength (FULL_VOTE_DB), the found share s is compared with the
    chance share p0 (event density x window width x share of position-compatible
    event pairs): score(L) = s [F ln(s / p0) + (V - F) ln((1 - s) / (1 - p0))], 0
    where s <= p0. The log-likelihood ratio grows with the number of checks at a
    given share, so the period beats twice it (fewer checks); the factor s favours
    the lag at which all rotors' flash trains are consistent over an inter-rotor lag
    or a sub-multiple that only some rotors fit (more checks, lower share). The best lag wins
    (centre of its plateau). Where a flash fits within one PRI (`_coherent`), the
    RERANK_N strongest lags are re-scored with the coherent partner checks (vote +
    RERANK_WEIGHT x share x coherent LLR), and the winner's half replaces it (once) when
    its coherent checks succeed about as often as the lag's (`_half_is_period`);
    otherwise the half replaces it while at least SUBHARMONIC_SHARE of the half's event
    checks find a partner and that share is not significantly (SUBHARMONIC_Z) below the
    lag's. The period is the mean of the event intervals matching multiples of the lag
    (after the wider event search: of those within TOL_FRACTION of the refined lag's);
    the score counts the same-place pairs one lag apart (+SECOND_PERIOD_GAIN per pair two
    lags apart).
    """
    e = series.energy
    n = e.size
    none = Periodicity(Estimate(0.0, 0.0), 0.0, 0, np.zeros(0), 0.0, 0.0)
    if n < 8 or float(e.max()) <= 0.0:
        return none
    par_db = 10.0 * math.log10(max(float(e.max()) / max(float(e.mean()), 1e-300), 1.0))
    times, pos = flash_events(series, series.radius)
    k = times.size
    lag_min = max(2.0, series.rate_hz / FLASH_RATE_MAX_HZ)
    lag_max = min(n * (1.0 - MIN_OVERLAP), series.rate_hz / FLASH_RATE_MIN_HZ)
    if k < 2 or lag_max <= lag_min:
        return Periodicity(Estimate(0.0, 0.0), 0.0, int(k), np.zeros(0), 0.0, par_db)
    strength = e[np.minimum(np.maximum(np.round(times).astype(int), 0), n - 1)] / max(series.threshold, 1e-300)
    weight = np.minimum(np.maximum(np.log10(1.0 + strength) * 10.0 / FULL_VOTE_DB, MIN_VOTE_WEIGHT), 1.0)
    lags = np.arange(math.ceil(lag_min), math.floor(lag_max) + 1, dtype=float)
    fraction = TOL_FRACTION if _coherent_applies(series) else EVENT_TOL_FRACTION
    vote, found_n, valid_n = _votes(times, pos, weight, lags, n, series.drift_bins_per_sample,
                                    series.per_bin.shape[1], fraction)
    best = float(vote.max())
    if best <= 0.0 or float(found_n.max()) <= 0.0:
        return Periodicity(Estimate(0.0, 0.0), 0.0, int(k), np.zeros(0), 0.0, par_db)
    i0 = int(np.argmax(vote))
    i1 = i0
    while i1 + 1 < lags.size and vote[i1 + 1] == best:
        i1 += 1
    lag0 = 0.5 * (lags[i0] + lags[i1])
    coh = _coherent(series, times)
    if coh is not None:
        lag0, half = _rerank(coh, times, weight, lags, vote, lag0, n)
        if half:
            lag0 /= 2.0  # once: the event vote errs by one missed flash between two
    else:
        lag0 = _event_half_rule(lags, vote, found_n, valid_n, lag0, fraction)
    diff = times[None, :] - times[:, None]  # (k, k): t_j - t_i
    intervals, matched, mult = matched_intervals(diff, lag0, fraction)  # the score's pairs
    periods = intervals[matched]
    if fraction > TOL_FRACTION and periods.size:  # a wide search's plateau centre: refine, match closely
        refined = float(periods.mean())
        narrow_intervals, narrow, _ = matched_intervals(diff, refined, TOL_FRACTION)
        if narrow.any():
            lag0, periods = refined, narrow_intervals[narrow]
    tol0 = TOL_SAMPLES + TOL_FRACTION * lag0
    period = float(periods.mean()) if periods.size else float(lag0)
    scatter = float(periods.std()) if periods.size > 1 else tol0
    period_std = math.sqrt(scatter ** 2 + 1.0 / 12.0) / math.sqrt(max(periods.size, 1))
    rate = series.rate_hz / period
    phases = np.mod(times / period, 1.0)
    moved = pos[None, :] - pos[:, None] - series.drift_bins_per_sample * diff
    informative = (pos > 0.0) & (pos < series.per_bin.shape[1] - 1)
    same_place = (np.abs(moved) <= POSITION_TOL_BINS) | ~informative[None, :] | ~informative[:, None]
    score = float(np.sum(matched & same_place & (mult == 1))
                  + SECOND_PERIOD_GAIN * np.sum(matched & same_place & (mult == 2)))
    return Periodicity(Estimate(rate, rate * period_std / period), score, int(k), phases,
                       tol0 / period, par_db, rotors_seen(flash_groups(times, period), period, n))


def _event_half_rule(lags: np.ndarray, vote: np.ndarray, found_n: np.ndarray, valid_n: np.ndarray,
                     lag0: float, fraction: float) -> float:
    """Halving by event checks alone (no complex field): the half replaces the lag while at
    least SUBHARMONIC_SHARE (and SUBHARMONIC_MIN_FOUND) of its checks find a partner and its
    share is not significantly (SUBHARMONIC_Z) below the lag's."""
    while lag0 / 2.0 >= lags[0]:
        sel = np.flatnonzero(np.abs(lags - lag0 / 2.0) <= TOL_SAMPLES + fraction * lag0 / 2.0)
        if sel.size == 0:
            break
        j = int(sel[np.argmax(vote[sel])])
        if found_n[j] < SUBHARMONIC_MIN_FOUND or found_n[j] < SUBHARMONIC_SHARE * valid_n[j]:
            break
        c = int(np.argmin(np.abs(lags - lag0)))
        pooled = (found_n[c] + found_n[j]) / max(valid_n[c] + valid_n[j], 1.0)
        se = math.sqrt(max(pooled * (1.0 - pooled), 1e-12) * (1.0 / max(valid_n[c], 1.0) + 1.0 / valid_n[j]))
        if found_n[c] / max(valid_n[c], 1.0) - found_n[j] / valid_n[j] > SUBHARMONIC_Z * se:
            break
        lag0 = float(lags[j])
    return lag0


def rotor_count(per: Periodicity) -> Estimate:
    """Distinct flash phases within one flash period = rotors (each flashes once per period).

    Flash times folded at the period are grouped circularly (gap > the matching
    tolerance starts a new group). A group seen once may be a missed-partner rotor
    or a noise event: its count is the value, half the singletons the uncertainty.
    """
    ph = np.sort(per.phases)
    if ph.size == 0:
        return Estimate(0.0, 0.0)
    gaps = np.diff(np.concatenate([ph, ph[:1] + 1.0]))
    breaks = gaps > max(per.tolerance, 1e-3)
    if not breaks.any():
        return Estimate(1.0, 0.0)
    starts = np.flatnonzero(breaks)
    sizes = np.diff(np.concatenate([starts, starts[:1] + ph.size]))
    singletons = int(np.sum(sizes == 1))
    return Estimate(float(sizes.size), 0.5 * singletons)


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
