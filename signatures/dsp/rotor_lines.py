"""Rotors visible in a long dwell's flash envelope: a count of what stands above the noise (docs/features.md,
"Long dwells").

A rotor flashes once per flash period at its own phase, and rotor rates differ by a fraction of a
per cent, so in the envelope folded at the flash rate each rotor is a straight line in phase against
time whose slope is its rate offset:

* windows of `PERIODS` flash periods are folded into one row each of a phase-time image (window x
  phase bin), each bin a mean with its own standard error (from the spread of the samples it
  averages);
* every line's sum over the windows (slopes within +-`MAX_DRIFT`) comes at once from zero-padded FFTs
  over the windows, one per phase harmonic, in units of the sum's standard error;
* lines are taken strongest first while one exceeds a Bonferroni threshold over the slopes and
  phases searched (`FALSE_LINES`: the chance that noise alone makes a line in a dwell); each is
  subtracted (its mean flash shape and skirts, fitted per window; the rows re-centred, since each
  row's mean held the line's power) before the next is sought, and a line that drifts less than a
  period from one already counted and either stays within its skirts for half the dwell or is a
  sliver of it (`RESIDUE_SHARE`) is that line's residue or that line bent;
* a line is counted only where its sum over the windows where it is clear of the lines counted
  before it (more than the flash's half width from each) also stands above the noise, at
  `FALSE_LINES` for the one line already located (`clear_z`): where two rotors' flashes coincide
  their fields add coherently and the first line's subtraction leaves a remainder, and a line
  drawn through such crossings gathers those remainders, not flashes of its own. No new constant;
  found on the 10 s conditions' over-counts (most were lines through crossings), checked on scenes
  0-39 and 40-159 of the four CW conditions apart.

The count is a lower bound: rotors whose flashes sit under the noise (untagged blades 6-15 dB under
tagged ones, an idle rotor's weak flashes) are not seen, and the verification reads it so
(`signatures.classify.verify`: more rotors than the claim has counts against it, fewer does not). numpy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["FALSE_LINES", "MIN_KNOWN_WINDOWS", "Line", "clear_z", "count_known", "phase_time", "searched_slopes",
           "visible_rotors"]

#: Flash periods folded into one window (row) of the phase-time image.
PERIODS = 4
#: Largest relative rate offset of a rotor from the folded rate that is searched.
MAX_DRIFT = 0.03
#: Chance that noise alone makes one line in a dwell (the Bonferroni threshold's level).
FALSE_LINES = 0.01
#: Most lines taken from one dwell.
MAX_LINES = 16
#: A line under this share of a counted one's z that drifts less than a period from it is what that
#: line's subtraction left (chosen on scenes 40-79 of the 10 s conditions, scored on 0-39).
RESIDUE_SHARE = 0.08
#: A line clear of the counted ones in fewer windows than this runs along one of them: it has no
#: stretch of its own to show flashes in, and is not counted (`clear_z`).
MIN_CLEAR_WINDOWS = 8
#: Zero-padding factor of the FFTs over windows (the slope sums' interpolation).
PAD = 8
#: A fold of fewer windows than this gives no count (`count_known`): its lines' slopes are too coarse
#: to keep rotors a fraction of a per cent apart, and a rate read at half the train's (idle rotors,
#: 0.82 s: 11-13 windows) folds each rotor's flashes twice a period, read as up to twice the rotors
#: (cw-idle-11111111, held-out scene 37: 9 lines on a quad). Every right rate of the CW conditions
#: folds 0.82 s into 23 windows or more.
MIN_KNOWN_WINDOWS = 16


@dataclass(frozen=True)
class Line:
    """One rotor's flashes: phase drift per window (bins), phase at window 0 (bin), and z (sum over
    windows in units of its standard error)."""

    slope: float
    phase: int
    z: float


def phase_time(envelope: np.ndarray, cycles_per_pulse: float, periods: int = PERIODS
               ) -> tuple[np.ndarray, np.ndarray]:
    """(image, variance): the envelope folded at `cycles_per_pulse` in windows of `periods` flash
    periods, each row less its mean (window, phase bin), and each bin mean's variance."""
    period = 1.0 / cycles_per_pulse
    bins = max(8, int(round(period)))
    win = max(1, int(round(periods * period)))
    rows = envelope.size // win
    t = np.arange(rows * win)
    phase = np.minimum(((t * cycles_per_pulse) % 1.0 * bins).astype(int), bins - 1)
    idx = (t // win) * bins + phase
    x = np.asarray(envelope[: rows * win], dtype=np.float64)
    count = np.maximum(np.bincount(idx, minlength=rows * bins), 1).reshape(rows, bins)
    mean = np.bincount(idx, weights=x, minlength=rows * bins).reshape(rows, bins) / count
    second = np.bincount(idx, weights=x * x, minlength=rows * bins).reshape(rows, bins) / count
    var = np.maximum(second - mean * mean, 0.0) / np.maximum(count - 1, 1)
    return mean - mean.mean(axis=1, keepdims=True), var


def clear_z(image: np.ndarray, noise_var: float, slope: float, phase: int, counted: list[Line], half: int
            ) -> tuple[float, int]:
    """(z, windows) of the line (`slope`, `phase`) of `image` (window x phase bin) summed over the
    windows where its centre lies more than `half` bins (the flash's half width) from every
    `counted` line's, in units of that sum's standard error (`noise_var`: a bin mean's variance).

    Why: where two rotors' flashes coincide (their lines cross, or run side by side) their fields
    add coherently, so the power there is not the sum of their powers, and the first line's
    subtraction leaves there a remainder of either sign: a line through a few such crossings can
    add up to the search's threshold with no flashes of its own. A rotor's line holds its flashes
    in every window, so its sum where it is clear of the counted lines stands above the noise
    as well; a remainder's does not."""
    rows, bins = image.shape
    j = np.arange(rows)
    clear = np.ones(rows, dtype=bool)
    for f in counted:
        apart = np.abs((phase - f.phase + (slope - f.slope) * j + bins / 2) % bins - bins / 2)
        clear &= apart > half
    n = int(clear.sum())
    if n == 0:
        return 0.0, 0
    centre = np.rint(phase + slope * j[clear]).astype(int) % bins
    return float(image[j[clear], centre].sum() / math.sqrt(noise_var * n)), n


def searched_slopes(rows: int, bins: int, periods: int = PERIODS, max_drift: float = MAX_DRIFT) -> np.ndarray:
    """The line slopes (phase bins per window) `visible_rotors` searches in a (rows x bins) image:
    rate offsets within +-`max_drift`, half a bin over the dwell apart. With the phases, the tests
    its Bonferroni threshold counts."""
    step = 0.5 / rows
    reach = max_drift * periods * bins
    return np.arange(-reach, reach + step / 2, step)


def count_known(samples: int, cycles_per_pulse: float, periods: int = PERIODS) -> bool:
    """Whether `visible_rotors` of an envelope of `samples` folded at `cycles_per_pulse` is a count
    (MIN_KNOWN_WINDOWS windows or more) rather than "not known"."""
    if not cycles_per_pulse > 0.0:
        return False
    return samples // max(1, int(round(periods / cycles_per_pulse))) >= MIN_KNOWN_WINDOWS


def visible_rotors(envelope: np.ndarray, cycles_per_pulse: float, periods: int = PERIODS,
                   max_drift: float = MAX_DRIFT, false_lines: float = FALSE_LINES) -> list[Line]:
    """The rotors whose flashes stand above the noise in a long dwell's flash envelope (module
    docstring), strongest first; [] for a rate of 0 or a dwell of fewer than 8 windows."""
    if not cycles_per_pulse > 0.0:
        return []
    image, var = phase_time(envelope, cycles_per_pulse, periods)
    rows, bins = image.shape
    if rows < 8:
        return []
    slopes = searched_slopes(rows, bins, periods, max_drift)
    from statistics import NormalDist  # ~5 ms to import (fractions, decimal): only where lines are searched

    z0 = NormalDist().inv_cdf(1.0 - false_lines / (slopes.size * bins))
    z_clear = NormalDist().inv_cdf(1.0 - false_lines)  # the line is located: one test, no search over slopes
    length = PAD * (1 << int(math.ceil(math.log2(rows))))
    m = np.fft.fftfreq(bins) * bins
    at = (m[None, :] * slopes[:, None] / bins) % 1.0 * length  # where each (slope, harmonic) reads
    k0 = np.floor(at).astype(int) % length
    k1 = (k0 + 1) % length
    frac = at - np.floor(at)
    cols = np.arange(bins)[None, :]
    noise = math.sqrt(float(np.mean(var)) * rows)
    if noise <= 0.0:
        return []
    j = np.arange(rows)
    work = image.copy()
    noise_var = float(np.mean(var))  # a bin mean's variance, for `clear_z`
    found: list[Line] = []
    half = None
    for _ in range(MAX_LINES):
        spread = np.fft.ifft(np.fft.fft(work, axis=1), n=length, axis=0) * length  # sum_j F_j[m] e^{2 pi i k j / L}
        sums = np.fft.ifft(spread[k0, cols] * (1 - frac) + spread[k1, cols] * frac, axis=1).real / noise
        si, p0 = np.unravel_index(int(np.argmax(sums)), sums.shape)
        if sums[si, p0] < z0:
            break
        s0 = float(slopes[si])
        centre = np.rint(p0 + s0 * j).astype(int)  # the line's bin in each window
        aligned = work[j[:, None], (centre[:, None] + np.arange(bins)[None, :]) % bins].mean(axis=0)
        if half is None:  # the flash's half width from the strongest line, at most an eighth of a period
            half = 1
            while half < bins // 8 and min(aligned[half], aligned[-half]) > 0.5 * aligned[0]:
                half += 1
        width = min(2 * half, bins // 4)  # the flash and its skirts: what is left of a line is no new line
        z = float(sums[si, p0])
        residue = any(abs(s0 - f.slope) * rows < bins  # drifts apart by less than a period over the dwell
                      and (z < RESIDUE_SHARE * f.z  # and is a sliver of it, or stays in its skirts
                           or np.mean(np.abs((p0 - f.phase + (s0 - f.slope) * j + bins / 2) % bins - bins / 2)
                                      <= width) >= 0.5) for f in found)
        counted = False
        if not residue:  # flashes of its own where it is clear of the counted (summed before its subtraction)
            own, windows = clear_z(work, noise_var, s0, int(p0), found, half)
            counted = windows >= MIN_CLEAR_WINDOWS and own >= z_clear
        offs = np.arange(-width, width + 1)
        at_line = (centre[:, None] + offs[None, :]) % bins
        shape = aligned[offs]
        amp = np.maximum(work[j[:, None], at_line] @ shape / max(float(shape @ shape), 1e-300), 0.0)
        work[j[:, None], at_line] -= amp[:, None] * shape[None, :]
        work -= work.mean(axis=1, keepdims=True)  # each row's mean held the line's power: re-centre
        if counted:
            found.append(Line(s0, int(p0), z))
    return found
