"""Time-frequency views of the slow-time signal at the target's range bins.

STFT by a strided sliding window and one batched FFT (8x faster here than
`scipy.signal.ShortTimeFFT`, and no 1 s `scipy.signal` import). Arrays are
(time, frequency), frequency fftshifted: Doppler from -PRF/2 to +PRF/2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from signatures.dsp import fft as _fft
from signatures.radar import RadarConfig
from signatures.dsp.rd import hann

#: STFT window length in seconds at 77 GHz, rounded to a power of two in chirps (paper 16, wide 64):
#: it resolves a ~30 us blade flash in time while keeping 1-2.5 kHz (4-10 m/s) Doppler resolution.
#: The window scales with the wavelength (`stft_params`), keeping that trade in blade motion.
STFT_WINDOW_S = 0.5e-3
STFT_REFERENCE_WAVELENGTH_M = 299_792_458.0 / 77e9
#: The frames' rate must carry the fastest blade-flash cadence (Hz): hop <= PRF / (2 x this).
STFT_MAX_CADENCE_HZ = 500.0


def stft_params(config: RadarConfig, n_chirps: int) -> tuple[int, int]:
    """(window, hop) in chirps: STFT_WINDOW_S scaled by the wavelength over 77 GHz's, as a power
    of two (at least 4, at most the dwell's power of two); hop a quarter of it, or less where the
    frame rate would not carry STFT_MAX_CADENCE_HZ (a low-PRF radar: 5 kHz gives hop 5)."""
    span = STFT_WINDOW_S * config.wavelength_m / STFT_REFERENCE_WAVELENGTH_M
    win = 2 ** max(2, round(math.log2(max(span / config.pri_s, 1.0))))
    win = min(win, max(4, 2 ** int(math.log2(max(n_chirps, 1)))))
    hop = min(max(1, win // 4), max(1, int(config.prf_hz / (2.0 * STFT_MAX_CADENCE_HZ))))
    return win, hop


@dataclass(frozen=True)
class Spectrogram:
    """Power spectrogram summed over range bins: power[t, f] (float32)."""

    power: np.ndarray  # (time, Doppler) or (time, Doppler, range bin)
    time_s: np.ndarray  # frame centres
    doppler_hz: np.ndarray  # fftshifted


def spectrogram(slow: np.ndarray, config: RadarConfig, win: int, hop: int,
                per_column: bool = False, fft_backend: str | None = None) -> Spectrogram:
    """Hann STFT of each column of `slow` (chirps x bins), power summed over the columns
    (power[t, f]) or kept per column (power[t, f, column]) with `per_column`; `fft_backend`
    as `signatures.dsp.fft.fft`'s `backend`.

    A dwell shorter than the window is zero-padded to one frame.
    """
    x = slow if slow.ndim == 2 else slow[:, None]
    if x.shape[0] < win:
        x = np.concatenate([x, np.zeros((win - x.shape[0], x.shape[1]), x.dtype)])
    frames = sliding_window_view(x, win, axis=0)[::hop]  # (n_frames, bins, win)
    spec = _fft.fft(frames, axis=-1, window=hann(win), backend=fft_backend)
    cell = spec.real ** 2 + spec.imag ** 2  # (frames, bins, win)
    if per_column:
        power = np.fft.fftshift(cell.transpose(0, 2, 1), axes=1)
    else:
        power = np.fft.fftshift(cell.sum(axis=1), axes=-1)
    t = (np.arange(power.shape[0]) * hop + win / 2) * config.pri_s
    f = np.fft.fftshift(np.fft.fftfreq(win, d=config.pri_s))
    return Spectrogram(power, t, f)


def mean_spectrogram(specs: list[Spectrogram]) -> Spectrogram:
    """Average of several spectrograms of the same shape (the paper's Fig. 3), each
    normalised to unit total power first so loud returns do not dominate."""
    acc = np.zeros_like(specs[0].power)
    for s in specs:
        acc += s.power / np.float32(max(float(s.power.sum()), float(np.finfo(np.float32).tiny)))
    return Spectrogram(acc / np.float32(len(specs)), specs[0].time_s, specs[0].doppler_hz)


@dataclass(frozen=True)
class Cadence:
    """Cadence-velocity diagram: |FFT over time| of each Doppler row of a spectrogram."""

    magnitude: np.ndarray  # float32 (n_cadence, n_doppler), cadence frequency >= 0
    cadence_hz: np.ndarray
    doppler_hz: np.ndarray

    def spectrum(self) -> np.ndarray:
        """Cadence spectrum summed over Doppler (float32; zero at DC: rows are mean-removed)."""
        return self.magnitude.sum(axis=1)


def cadence(spec: Spectrogram, fft_backend: str | None = None) -> Cadence:
    """CVD of a spectrogram. Periodic blade flashes give lines at multiples of the flash
    rate whatever the Doppler does, so it survives blade-tip aliasing. `fft_backend` as
    `signatures.dsp.fft.fft`'s `backend` (numpy: float64 transform; scipy: float32)."""
    p = spec.power - spec.power.mean(axis=0, keepdims=True)
    mag = np.abs(_fft.rfft(p, axis=0, backend=fft_backend)).astype(p.dtype, copy=False)
    step = float(spec.time_s[1] - spec.time_s[0]) if spec.time_s.size > 1 else 1.0
    return Cadence(mag, np.fft.rfftfreq(p.shape[0], d=step), spec.doppler_hz)
