"""The held-out receiver: its clutter, its noise and its imperfections.

Clutter: a few discrete stationary scatterers at arbitrary (off-grid) ranges plus a diffuse
floor of many weak scatterers whose returns fluctuate slowly (vegetation sway: a Gaussian
Doppler spectrum 0.02-0.15 m/s wide carrying 3-20 % of the diffuse power). Noise: circular
white Gaussian, its realised power scaled exactly (the SNR definition). Imperfections, in
signal order: oscillator phase noise (a slow random walk from chirp to chirp plus white
jitter) on everything that went through the air, IQ gain and phase imbalance, a DC offset,
and a 12-bit ADC whose full scale an AGC sets at 4.5x the rms of a rail.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signatures.radar import C, RadarConfig


@dataclass(frozen=True)
class ReceiverTruth:
    phase_walk_rad: float
    phase_jitter_rad: float
    iq_gain: float
    iq_phase_deg: float
    dc_dbc: float
    adc_bits: int


def _beats(ranges_m: np.ndarray, config: RadarConfig, n_samples: int) -> np.ndarray:
    """(points, samples) fast-time response of stationary scatterers, carrier phase included."""
    lam = C / config.carrier_hz
    tau = 2.0 * (ranges_m - config.range_offset_m) / C
    t_k = np.arange(n_samples) / config.sample_rate_hz
    phase = (4 * math.pi * ranges_m / lam)[:, None] + 2 * math.pi * config.slope_hz_per_s * tau[:, None] * t_k[None, :]
    return np.exp(1j * np.mod(phase, 2 * math.pi))


def clutter(config: RadarConfig, n_chirps: int, n_samples: int, power: float, rng: np.random.Generator) -> np.ndarray:
    """Discrete plus diffuse ground clutter of mean power `power` per IF sample, complex64."""
    lo, hi = config.range_window_m
    n_disc = int(rng.integers(2, 9))
    disc_r = rng.uniform(lo, hi, n_disc)
    disc_a = np.sqrt(rng.exponential(1.0, n_disc)) * np.exp(1j * rng.uniform(0, 2 * math.pi, n_disc))
    n_diff = 2 * n_samples
    diff_r = rng.uniform(lo, hi, n_diff)
    diff_a = (rng.standard_normal(n_diff) + 1j * rng.standard_normal(n_diff)) * np.sqrt(0.5 / n_diff)
    disc_a *= math.sqrt(rng.uniform(0.3, 0.7) / max(float(np.sum(np.abs(disc_a) ** 2)), 1e-30))
    # diffuse fluctuation: white noise shaped to a Gaussian Doppler spectrum, unit power per column
    sigma_hz = 2.0 * rng.uniform(0.02, 0.15) * config.carrier_hz / C
    f = np.fft.fftfreq(n_chirps, d=config.pri_s)
    shape = np.exp(-0.25 * (f / sigma_hz) ** 2)
    white = (rng.standard_normal((n_chirps, 2 * n_diff), dtype=np.float32).view(np.complex64))
    sway = np.fft.ifft(white * shape[:, None].astype(np.float32), axis=0)
    sway /= np.sqrt(np.mean(np.abs(sway) ** 2))
    moving = rng.uniform(0.03, 0.2)
    slow = diff_a[None, :] * (math.sqrt(1 - moving) + math.sqrt(moving) * sway)
    cube = (slow @ _beats(diff_r, config, n_samples)) + (disc_a @ _beats(disc_r, config, n_samples))[None, :]
    cube *= math.sqrt(power / max(float(np.mean(np.abs(cube) ** 2)), 1e-300))
    return cube.astype(np.complex64)


def thermal_noise(n_chirps: int, n_samples: int, power: float, rng: np.random.Generator) -> np.ndarray:
    """Circular white Gaussian noise whose realised mean power is exactly `power`."""
    z = (rng.standard_normal((n_chirps, n_samples)) + 1j * rng.standard_normal((n_chirps, n_samples)))
    z *= math.sqrt(power / float(np.mean(np.abs(z) ** 2)))
    return z.astype(np.complex64)


def receive(through_air: np.ndarray | None, noise: np.ndarray | None, shape: tuple[int, int],
            rng: np.random.Generator) -> tuple[np.ndarray, ReceiverTruth]:
    """What the ADC hands over: phase noise on the echoes, noise added, IQ imbalance, DC, quantisation."""
    truth = ReceiverTruth(phase_walk_rad=float(rng.uniform(2e-5, 2e-4)),
                          phase_jitter_rad=float(rng.uniform(1e-3, 5e-3)),
                          iq_gain=float(rng.uniform(-0.05, 0.05)), iq_phase_deg=float(rng.uniform(-2.0, 2.0)),
                          dc_dbc=float(rng.uniform(-30.0, -20.0)), adc_bits=12)
    n_chirps, n_samples = shape
    walk = np.cumsum(rng.normal(0.0, truth.phase_walk_rad, n_chirps))
    jitter = rng.normal(0.0, truth.phase_jitter_rad, shape)
    x = np.zeros(shape, dtype=np.complex128)
    if through_air is not None:
        x += through_air * np.exp(1j * (walk[:, None] + jitter))
    if noise is not None:
        x += noise
    psi = math.radians(truth.iq_phase_deg)
    i_rail = x.real
    q_rail = (1.0 + truth.iq_gain) * (x.imag * math.cos(psi) + x.real * math.sin(psi))
    rms = math.sqrt(max(float(np.mean(np.abs(x) ** 2)), 1e-300))
    dc = rms * 10 ** (truth.dc_dbc / 20) * np.exp(1j * rng.uniform(0, 2 * math.pi))
    i_rail = i_rail + dc.real
    q_rail = q_rail + dc.imag
    full_scale = 4.5 * rms / math.sqrt(2.0)
    step = 2.0 * full_scale / 2 ** truth.adc_bits
    top = 2 ** (truth.adc_bits - 1)
    out = np.empty(shape, dtype=np.complex64)
    out.real = np.clip(np.round(i_rail / step), -top, top - 1) * step
    out.imag = np.clip(np.round(q_rail / step), -top, top - 1) * step
    return out, truth
