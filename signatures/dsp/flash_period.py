"""The blade-flash period search, array-first: flash rate, rotor count and rotors seen of B flash
series at once (`signatures.dsp.flash_series`; one return is B = 1).

Find flash events (local maxima) and their range positions; score each candidate period L by how
consistently the events repeat at +-L: every event whose partner window lies inside the dwell
checks for a same-place event there, and the share of checks that succeed is tested against the
chance share (a binomial log-likelihood ratio). All rotors of an airframe share the rate (phases
differ), so at the true period every rotor's checks succeed, while an inter-rotor lag or a
sub-multiple is refuted by the rotors that do not fit it. Flashes are treated as events, not
weighted by energy: in the `paper` preset a two-blade flash (main lobe ~20 us) sampled once per
44 us PRI varies by up to ~20 dB with where it falls between chirps, and energy-weighted
autocorrelations then lock onto the few strongest flashes of different rotors (inter-rotor lags).

Coherent partner checks: the flashes of one rotor come from the same hub, so they
share its range position and, a period later, its carrier phase up to the
sign of the sinc (the body Doppler is removed; wobble moves the hub little within a
period). The event's matched-filter output, kept in phase with it, finds that
rotor's weaker flashes below the energy threshold, while
another rotor's flash (another hub range, a random phase) mostly fails it. These
checks re-rank the best candidate periods of the event vote and decide whether half
the chosen period is the period (in `paper` a flash one period later is often sampled
between chirps and missed, so twice the period can win the event vote).

Row b of `periodicity_batch` equals the straightforward per-return form of the search
(tests/features/reference_flash.py, "the reference") to the bit (tests/features/test_batch_estimators.py):
the same float operations on the same values in the same order, so that no discrete decision (an
event, a lag, a halving, a rotor group) depends on the batch. How:

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

Scratch memory stays under MEMORY_BUDGET_BYTES (groups of rows).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signatures.dsp.flash_series import FLASH_RATE_MAX_HZ, FLASH_RATE_MIN_HZ, MEMORY_BUDGET_BYTES, FlashSeriesBatch
from signatures.dsp.stats import distinct

__all__ = ["BLADES_ASSUMED", "PeriodicityBatch", "binomial_llr", "events_kept", "flash_groups", "matched_intervals",
           "peak_positions", "periodicity_batch", "rotors_seen"]

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
#: Flash events rise above the sinc skirt of every stronger event within SKIRT_REACH samples:
#: SKIRT_DB - 20 log10(distance).
SKIRT_REACH = 12
SKIRT_DB = -13.0
#: Blades per rotor (as the shipped profiles have): two opposite blades flash together, so the
#: rotor rate is the flash rate over BLADES_ASSUMED.
BLADES_ASSUMED = 2
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
#: Flash events kept per series (the strongest): MAX_EVENTS, and this many per second of
#: dwell beyond it (64 in the `paper` and `wide` dwells of 26 and 51 ms; ~1,000 in 0.82 s).
MAX_EVENTS = 64
MAX_EVENTS_PER_S = 1200.0
#: Rotors seen: events closer than this share of the flash period (at least GROUP_GAP_SAMPLES)
#: are one flash. A blade made of several scatterers flashes as a cluster of peaks, while one
#: rotor flashes once per period and per-rotor rates differ by a few per cent.
GROUP_GAP_PERIODS = 0.03
GROUP_GAP_SAMPLES = 3.0
#: Rows with the same number of events are processed in groups of about this much scratch: one
#: large group spends a third of the vote's time faulting in fresh pages; a few tens of MiB
#: reuse the allocator's memory.
GROUP_BYTES = 32 * 2**20
_SIGNS = np.array([1.0, -1.0])


def peak_positions(profiles: np.ndarray) -> np.ndarray:
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


def events_kept(dwell_s: float) -> int:
    """Flash events kept per series: MAX_EVENTS, or MAX_EVENTS_PER_S of the dwell where longer
    (a long dwell holds proportionally more flashes; a fixed cap would keep a few of them)."""
    return max(MAX_EVENTS, math.ceil(MAX_EVENTS_PER_S * dwell_s))


def binomial_llr(found: np.ndarray, made: np.ndarray, share: np.ndarray,
                 chance: np.ndarray) -> np.ndarray:
    """found of made checks at success share `share` against `chance`; 0 where share <= chance."""
    s = np.minimum(np.maximum(share, 1e-9), 1.0 - 1e-9)
    llr = found * np.log(s / chance) + (made - found) * np.log((1.0 - s) / (1.0 - chance))
    return np.where((s > chance) & (made > 0.0), llr, 0.0)


def matched_intervals(diff: np.ndarray, lag: float | np.ndarray,
                      fraction: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(intervals over their multiple, matched mask, multiples) of the event pairs (diff: t_j - t_i,
    (k, k), or (rows, k, k) with `lag` broadcast against it, as the batch path calls it): matched
    where the interval lies within TOL_SAMPLES + fraction x (multiple x lag) of a multiple of `lag`."""
    mult = np.round(diff / lag)
    matched = (diff > 0) & (mult >= 1) & (np.abs(diff - mult * lag) <= TOL_SAMPLES + fraction * mult * lag)
    return diff / np.maximum(mult, 1), matched, mult


def flash_groups(times: np.ndarray, period: np.ndarray) -> np.ndarray:
    """Distinct flashes among each row's time-sorted events (rows, k), int (rows,): a gap wider
    than GROUP_GAP_PERIODS of the row's period (and GROUP_GAP_SAMPLES) starts a new one."""
    times = np.asarray(times, dtype=np.float64)
    if times.shape[1] == 0:
        return np.zeros(times.shape[0], dtype=int)
    gap = np.maximum(GROUP_GAP_SAMPLES, GROUP_GAP_PERIODS * np.asarray(period, dtype=np.float64))
    return 1 + np.count_nonzero(np.diff(times, axis=1) > gap[:, None], axis=1)


def rotors_seen(groups: np.ndarray, period: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Rate-invariant rotor count per row, (value, std): distinct flashes over the flash periods the
    dwell of n samples holds; 0 and 0 where there are no groups or no period.

    Each rotor flashes once per flash period (the period is the time between its blades passing
    broadside), so flashes per period count the rotors whatever the rotor rate. Two rotors flashing
    within the group gap count once and missed flashes not at all, so it undercounts a little;
    its relative uncertainty is that of a count, 1 / sqrt(groups)."""
    groups = np.asarray(groups, dtype=np.float64)
    period = np.asarray(period, dtype=np.float64)
    live = (groups > 0.0) & (period > 0.0) & (n > 0)
    value = np.where(live, groups * period / max(n, 1), 0.0)
    return value, np.where(live, value / np.sqrt(np.where(live, groups, 1.0)), 0.0)


@dataclass(frozen=True)
class PeriodicityBatch:
    """Per row: the flash rate, its score and events, and the rotors (the reference's `periodicity` and
    `rotor_count`)."""

    flash_rate_hz: np.ndarray  # (B,) float64, 0 where no periodicity
    flash_rate_std_hz: np.ndarray
    score: np.ndarray
    n_events: np.ndarray  # (B,) int
    flash_par_db: np.ndarray
    rotor_count: np.ndarray
    rotor_count_std: np.ndarray
    rotors_seen: np.ndarray  # `rotors_seen`: distinct flashes per flash period
    rotors_seen_std: np.ndarray


def periodicity_batch(series: FlashSeriesBatch, max_events: int | None = None) -> PeriodicityBatch:
    """The reference's `periodicity` and `rotor_count` of every row.

    Stages that depend on the number of events k run per group of rows with the same k (the
    votes, the coherent hits and checks, the period); those on the lag axis alone (plateau,
    re-rank candidates, halving rule) run over the whole batch at once."""
    e = series.energy
    b_rows, n = e.shape
    if max_events is None:
        max_events = events_kept(n / series.rate_hz)
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
        seen, seen_std = rotors_seen(flash_groups(times[sub, :kk], period), period, n)
        for name, values in (("rate", rate), ("std", std), ("score", score), ("rotors", rotors),
                             ("rotors_std", rotors_std), ("seen", seen), ("seen_std", seen_std)):
            out[name][sub] = values


def _flash_events(e: np.ndarray, threshold: np.ndarray, per_bin: np.ndarray, radius: int,
                  max_events: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference's `flash_events` of every row: times and positions (B, K) sorted by time in the
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
    positions = peak_positions(profiles.reshape(-1, per_bin.shape[2])).reshape(peaks.shape)
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
    """The reference's `_votes` of a group (partner tolerance TOL_SAMPLES + fraction x lag): (vote,
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
    """The reference's `_coherent` of a group: hit counts (g, k, n + 1) and the chance share (g,).
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
    """The reference's `_coherent_checks` with per-row lags (g, m), before the weighted sums: the checks
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
    """The greedy candidates of the reference's `_rerank` for every row: (lags, vote scores) (rows, RERANK_N)
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
    """The choice of the reference's `_rerank` among each row's n_c candidates (rows with the same k),
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
    llr = binomial_llr(f1, m1, s, chance[:, :cm]) + binomial_llr(f2, m2, s, chance[:, cm:2 * cm])
    total = np.where(np.arange(cm)[None, :] < n_c[:, None], scores[:, :cm] + RERANK_WEIGHT * s * llr, -np.inf)
    best = np.argmax(total, axis=1)
    si = np.arange(g)
    lag = cl[si, best]
    half = (lag / 2.0 >= lags[0]) & _half_is_period(f1[si, best], m1[si, best], fh[si, best], mh[si, best],
                                                    chance[si, 2 * cm + best])
    return np.where(half, lag / 2.0, lag)


def _half_is_period(found: np.ndarray, made: np.ndarray, found_h: np.ndarray, made_h: np.ndarray,
                    chance_h: np.ndarray) -> np.ndarray:
    """The reference's `_half_is_period`, elementwise."""
    s0 = np.minimum(found / np.where(made > 0.0, made, 1.0), HALF_SHARE_CAP)
    llr = binomial_llr(found_h, made_h, s0, chance_h)
    return (made > 0.0) & (made_h > 0.0) & (found_h >= 1.0) & (llr > HALF_LLR)


def _event_half_rule(lags: np.ndarray, vote: np.ndarray, found_n: np.ndarray, valid_n: np.ndarray,
                     lag0: np.ndarray, fraction: float) -> np.ndarray:
    """The reference's `_event_half_rule` of a group: a loop over halvings, vectorised over rows."""
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
    """The tail of the reference's `periodicity` for a group: rate, rate std, score, phases, tolerance
    (in periods), period (series samples). After a search wider than TOL_FRACTION the lag is
    refined and matched again closely where that matches anything, as the reference; the score
    counts the search's pairs. Mean and std of the matched intervals run per match count (numpy's
    pairwise sums depend on the length); the scalar tail in Python floats, as the reference."""
    g, k = times.shape
    diff = times[:, None, :] - times[:, :, None]
    intervals, matched, mult = matched_intervals(diff, lag0[:, None, None], fraction)  # the score's pairs
    n_matched, mean, spread = _interval_stats(intervals, matched, lag0)
    if fraction > TOL_FRACTION:
        narrow_intervals, narrow, _ = matched_intervals(diff, mean[:, None, None], TOL_FRACTION)
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
    """The reference's `rotor_count` of rows of k >= 2 phases: circular groups split at gaps > tol."""
    ph = np.sort(phases, axis=1)
    gaps = np.diff(np.concatenate([ph, ph[:, :1] + 1.0], axis=1), axis=1)
    breaks = gaps > np.maximum(tol, 1e-3)[:, None]
    groups = breaks.sum(axis=1)
    singletons = (breaks & np.roll(breaks, -1, axis=1)).sum(axis=1)
    return np.where(groups > 0, groups, 1).astype(float), np.where(groups > 0, 0.5 * singletons, 0.0)
