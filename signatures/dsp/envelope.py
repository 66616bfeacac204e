"""The flash envelope's autocorrelation: the timing pattern of a target's blade flashes.

The flash-event estimator reduces a dwell's flashes to one rate and a count. The pattern itself
(a rotor set's flashes interleaving, a tagged blade flashing once per turn, rotors at slightly
different rates drifting apart) lives in the envelope of the micro-Doppler power over time; its
autocorrelation at fixed physical lags carries that pattern to the classifier. Fitted on the
training world only, it carries over to the held-out world where the other features do not
(docs/features.md, "Flash envelope").

Lags are physical (seconds): the same features serve any PRF, carrier and dwell. The envelope is
the log of the STFT power off the body line (`BODY_MPS` either side, so that a moving body does not
swamp it), summed over the target's bin +- 1, at frames of `WINDOW_S` (a power of two in chirps)
hopped by a quarter; its autocorrelation, normalised by the zero lag, is read at `LAGS_S` by linear
interpolation. Lags the dwell does not reach read 0. The log and the mean removal make every value
independent of the return's scale; each lies in [-1, 1].
"""

from __future__ import annotations

import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from signatures.radar import RadarConfig
from signatures.dsp.rd import hann

#: Autocorrelation lags (s): every 2 ms to 30 ms, one flash period of the fastest airframes to two
#: rotor turns of the slowest (flash rates 50-500 Hz). `FEATURE_NAMES` holds one `flash_ac_<ms>ms` each.
LAGS_S: tuple[float, ...] = tuple(0.002 * k for k in range(1, 16))
#: Frame length (s): long enough that each frame averages several chirps' noise (measured best of
#: 0.7-5.6 ms on the `paper` waveform: lab/bench/reach.py's transfer rows), short against a flash period.
WINDOW_S = 2.8e-3
#: Radial speeds within this of the body line are left out of the envelope (m/s).
BODY_MPS = 3.0
#: The envelope's floor relative to the mean frame power: the slow time arrives in float32.
RESOLUTION = 1e-6
#: An envelope whose mean square (log units) is at most this is flat: its autocorrelation reads 0.
FLAT = 1e-9
_FLOOR = 1e-300


def frames(config: RadarConfig, n_chirps: int) -> tuple[int, int]:
    """(window, hop) in chirps: `WINDOW_S` as a power of two (at least 4, at most the dwell's), hop a quarter."""
    win = 2 ** max(2, round(math.log2(max(WINDOW_S / config.pri_s, 1.0))))
    win = min(win, max(4, 2 ** int(math.log2(max(n_chirps, 1)))))
    return win, max(1, win // 4)


def autocorrelation(cols: np.ndarray, config: RadarConfig, body_hz: np.ndarray,
                    lags_s: tuple[float, ...] = LAGS_S) -> np.ndarray:
    """(B, len(lags_s)) float32 from the slow time `cols` (B, chirps, columns) of each row's target,
    whose body line lies at `body_hz` (B,). The reference: the feature path computes the same
    spectrogram with its batched FFTs and calls `from_spectrogram`."""
    cols = np.asarray(cols)
    n = cols.shape[1]
    win, hop = frames(config, n)
    if cols.shape[0] == 0 or n < win + 2 * hop:
        return np.zeros((cols.shape[0], len(lags_s)), dtype=np.float32)
    # float64: the frames' powers then neither overflow nor round at any scale of the input
    x = sliding_window_view(cols.astype(np.complex128, copy=False), win, axis=1)[:, ::hop]  # (B, frames, columns, win)
    spec = np.fft.fft(x * hann(win), axis=-1)
    power = np.fft.fftshift((spec.real ** 2 + spec.imag ** 2).sum(axis=2), axes=-1)
    return from_spectrogram(power, config, body_hz, hop, lags_s)


def from_spectrogram(power: np.ndarray, config: RadarConfig, body_hz: np.ndarray, hop: int,
                     lags_s: tuple[float, ...] = LAGS_S) -> np.ndarray:
    """`autocorrelation` from the target's spectrogram: `power` (B, frames, window) summed over its
    columns, Doppler fftshifted, frames `hop` chirps apart (`frames`); fewer than 3 frames (a dwell
    too short for the window) read 0."""
    rows, m, win = power.shape
    out = np.zeros((rows, len(lags_s)), dtype=np.float32)
    if rows == 0 or m < 3:
        return out
    bin_hz = config.prf_hz / win
    k = np.arange(win)[None, :] - win // 2  # signed bin numbers, fftshifted
    body = np.asarray(body_hz, dtype=np.float64).reshape(-1, 1) / bin_hz
    dist = np.abs((k - body + win / 2) % win - win / 2)
    keep = dist > max(1.0, BODY_MPS / (bin_hz * config.wavelength_m / 2.0))
    p = power.astype(np.float64, copy=False)
    off = np.einsum("bfk,bk->bf", p, keep.astype(np.float64))
    # off-body power below float32's resolution of the frame's total is rounding, not a flash
    floor = np.maximum(p.sum(axis=2).mean(axis=1, keepdims=True) * RESOLUTION, _FLOOR)
    env = np.log(np.maximum(off, floor))
    env -= env.mean(axis=1, keepdims=True)
    n_fft = 1 << int(2 * m - 1).bit_length()
    s = np.fft.rfft(env, n_fft, axis=1)
    ac = np.fft.irfft(s.real ** 2 + s.imag ** 2, n_fft, axis=1)[:, :m]
    zero = ac[:, :1]
    flat = zero <= m * FLAT  # no envelope to speak of (an empty or constant return)
    ac = np.where(flat, 0.0, ac / np.maximum(zero, _FLOOR))
    at = np.asarray(lags_s, dtype=np.float64) / (hop * config.pri_s)
    i = np.floor(at).astype(int)
    frac = at - i
    inside = i + 1 < m
    i = np.minimum(i, m - 2)
    vals = ac[:, i] * (1.0 - frac) + ac[:, i + 1] * frac
    out[:] = np.clip(np.where(inside[None, :], vals, 0.0), -1.0, 1.0)
    return out
