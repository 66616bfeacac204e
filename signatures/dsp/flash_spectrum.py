"""The flash rate of long dwells from the flash train's envelope spectrum, array-first: B gates of
returns that share a radar configuration at once (one return is B = 1). A dwell of SPECTRAL_DWELL_S
or more holds hundreds of flashes, and the period search (`signatures.dsp.flash_period`) keeps only its
strongest events; `spectral_flash_rate` says how the spectrum reads the rate, and
`signatures.dsp.rotor_lines` counts the rotors visible in the envelope (docs/long-dwells.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signatures.dsp.flash_series import FLASH_RATE_MAX_HZ, FLASH_RATE_MIN_HZ
from signatures.radar import RadarConfig
from signatures.dsp.rotor_lines import count_known, visible_rotors
from signatures.dsp.stats import median_last

__all__ = ["SPECTRAL_DETECT_SCORE", "SPECTRAL_DWELL_S", "TRACK_RATE_WINDOW", "TRACK_READ_SCORE", "FlashCurve",
           "FlashTrain", "flash_envelope", "line_width_hz", "spectral_flash_rate", "taper_length", "tukey"]

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
#: The same for the score with the turn's lines in the difference added (`_turn_score`): derived
#: as SPECTRAL_NOISE_LOG was, so that noise and clutter alone score no higher with them than without
#: (highest log peak-to-median at the rate read over 1,200 noise and clutter dwells, 0-20 dB, clutter
#: none to +60 dB, `cw-sband` and 5000.1 Hz, training and held-out worlds: 0.94 with them, 1.30 without;
#: 0.9 leaves them at most 0.04 there).
SPECTRAL_TURN_NOISE_LOG = 0.9
#: A long dwell's rotors visible (`signatures.dsp.rotor_lines`) are a count: its std is one line (a
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


#: A track's dwells read at the rate the track's own trains agree on (`FlashCurve.read_near`) look
#: within this share of it either way: the rotors' rate wanders that little over a track (a 5 %
#: estimate is right by the estimators' own measure).
TRACK_RATE_WINDOW = 0.05
#: ... and a dwell's score there is a flash train from this level: noise and clutter alone reach it
#: in 0.06 % of such windows (300 noise and clutter dwells, 0-20 dB, clutter none to +60 dB,
#: `cw-sband` and 5000.1 Hz, training and held-out worlds, a window at every 2 Hz of 40-480 Hz:
#: 66,000 windows, 0.1 % at 0.0, 0.035 % at 0.1, highest 0.11). A search of one window of the whole
#: range needs far less than the search's own bar (SPECTRAL_DETECT_SCORE), which holds over all of
#: it; a window's noise peak read at the track's rate repeats the track's rate, whatever the claim.
TRACK_READ_SCORE = 0.05


@dataclass(frozen=True)
class FlashCurve:
    """One long dwell's flash score at every candidate rate (`spectral_flash_rate` reads its rate
    at the best of them): what a track's dwell is read near the track's rate from."""

    rates_hz: np.ndarray  # the candidates (float32, ascending, one envelope bin apart)
    scores: np.ndarray  # the score at each, as `FlashTrain.score` reads it at the rate

    def read_near(self, rate_hz: float) -> tuple[float, float, float] | None:
        """(rate, std, score) of the best candidate within TRACK_RATE_WINDOW of `rate_hz` (at least
        the nearest bin each way), None where none reaches TRACK_READ_SCORE, `rate_hz` is no rate,
        or the curve is empty. The std is the search's (`spectral_flash_rate`): half a bin over
        sqrt(SPECTRAL_HARMONICS)."""
        hz = np.asarray(self.rates_hz, dtype=np.float64)
        if not (math.isfinite(rate_hz) and rate_hz > 0.0) or hz.size < 2:
            return None
        df = float(hz[1] - hz[0])
        near = np.abs(hz - rate_hz) <= max(TRACK_RATE_WINDOW * rate_hz, df)
        if not near.any():
            return None
        scores = np.where(near, np.asarray(self.scores, dtype=np.float64), -np.inf)
        best = int(np.argmax(scores))
        if not scores[best] >= TRACK_READ_SCORE:  # NaN too
            return None
        return float(hz[best]), 0.5 * df / math.sqrt(SPECTRAL_HARMONICS), float(scores[best])


@dataclass(frozen=True)
class FlashTrain:
    """What the envelope of a long dwell gives per row (B,): see `spectral_flash_rate`."""

    rate_hz: np.ndarray
    rate_std_hz: np.ndarray
    score: np.ndarray
    rotors_seen: np.ndarray  # rotors visible: a lower bound (`signatures.dsp.rotor_lines`)
    rotors_seen_std: np.ndarray
    rotors_known: np.ndarray | None = None  # bool: False where the fold gives no count (`count_known`)
    #: each row's score at every candidate rate (B, candidates), as `score` reads it at the rate
    #: (`FlashCurve`); None where the dwell is too short for a search
    curve: np.ndarray | None = None
    curve_hz: np.ndarray | None = None  # the candidate rates (candidates,)


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
    std and score, and the rotors visible (`signatures.dsp.rotor_lines.visible_rotors`: a lower bound).

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
    train), or where higher the same with the turn's lines in the difference added
    (`_turn_score`); the rate does not depend on it."""
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
    sum_curve, turn_curve = _log_curve(harm), _log_curve(_with_turn_lines(harm, asym, cand, own))
    score = np.maximum(np.maximum(sum_curve[rows, best] - SPECTRAL_NOISE_LOG,
                                  _turn_score(turn_curve, cand, rate / df)), 0.0)
    curve = np.maximum(sum_curve - SPECTRAL_NOISE_LOG, turn_curve - SPECTRAL_TURN_NOISE_LOG)
    live = harm[rows, best] > 0.0
    rate = np.where(live, rate, 0.0)
    std = np.where(live, np.where(turn, 2.0, 1.0) * 0.5 * df / math.sqrt(SPECTRAL_HARMONICS), 0.0)
    edge = taper_length(n, ENVELOPE_TAPER)  # the rotors are counted where the envelope is not tapered
    known = np.array([count_known(n - 2 * edge, rate[b] * config.pri_s) for b in range(b_rows)], dtype=bool)
    seen = np.array([float(len(visible_rotors(total[b, edge:n - edge], rate[b] * config.pri_s))) if known[b] else 0.0
                     for b in range(b_rows)])
    return FlashTrain(rate, std, np.where(live, score, 0.0), seen, np.where(seen > 0.0, VISIBLE_STD, 0.0),
                      known | ~live, curve.astype(np.float32), (cand * df).astype(np.float32))


def _log_curve(stat: np.ndarray) -> np.ndarray:
    """ln of each row's statistic (B, candidates) over its median, at every candidate."""
    return np.log(np.maximum(stat, 1e-300) / np.maximum(median_last(stat), 1e-300)[:, None])


def _with_turn_lines(harm: np.ndarray, asym: np.ndarray, cand: np.ndarray, own: np.ndarray) -> np.ndarray:
    """The capped harmonic sum `harm` of the sum's spectrum plus the whitened difference `asym` at the
    odd harmonics of the turn, (k - 1/2) times each candidate (k = 1..SPECTRAL_HARMONICS, within k / 2
    bins, capped as the sum's are). A tagged blade's power alternates sides once a turn, so the
    difference carries the turn where the sum cancels it: at low SNR those lines are half the
    train's evidence. Equal blades leave the difference noise, which the sum's own score carries."""
    width = asym.shape[1]
    total = harm.copy()
    for k in range(1, SPECTRAL_HARMONICS + 1):
        reach = k // 2
        idx = np.rint(cand * (k - 0.5)).astype(int)
        ok = idx + reach < width
        near = np.max(np.stack([asym[:, idx[ok] + d] for d in range(-reach, reach + 1)]), axis=0)
        total[:, ok] += np.minimum(near, HARMONIC_CAP * own[:, ok])
    return total


def _turn_score(turn_curve: np.ndarray, cand: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """Each row's score of its flash rate `rate` (fractional bins) from the log peak-to-median curve of
    the harmonic sum with the turn's lines (`_with_turn_lines`, `_log_curve`), read within a bin of
    the rate, less SPECTRAL_TURN_NOISE_LOG."""
    at = np.rint(rate).astype(int) - cand[0]
    rows = np.arange(turn_curve.shape[0])
    peak = np.max([turn_curve[rows, np.clip(at + d, 0, cand.size - 1)] for d in (-1, 0, 1)], axis=0)
    return np.where((at >= -1) & (at <= cand.size), peak - SPECTRAL_TURN_NOISE_LOG, 0.0)


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
