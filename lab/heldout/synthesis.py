"""Dechirped IF of point scatterers with their exact delays, by a Jacobi-Anger expansion.

A scatterer at range R (at the chirp's start) moving at v contributes, at fast time t_k,

    a * exp(j*(4*pi*R/lambda - pi*S*tau^2)) * exp(j*2*pi*(S*tau + 2*v/lambda)*t_k),   tau = 2*(R - R_off)/c

(beat frequency, carrier phase, residual video phase, and the intra-chirp Doppler that
couples range and Doppler; the S*2*v*t^2/c term is below 1e-2 rad and left out). Every
scatterer has its own frequency in every chirp, so the cube is not a product of slow- and
fast-time factors. Around the chirp's mid frequency omega_0, a scatterer's offset phase
beta*x (x in [-1, 1] over the samples, |beta| <= B) expands exactly as

    exp(j*beta*x) = sum_m eps_m * j^m * J_m(B*x) * T_m(beta/B)

(Chebyshev T_m, eps_0 = 1, eps_m = 2), truncated where |J_m(B)| < 1e-7. The sum over
scatterers then runs once per term on (chirps x scatterers) arrays and one small matrix
product gives the samples: exact to float32 precision without a (chirps x scatterers x
samples) array.
"""

from __future__ import annotations

import math

import numpy as np

from signatures.radar import C, RadarConfig

TOLERANCE = 1e-7


def bessel_j(orders: np.ndarray, z: np.ndarray) -> np.ndarray:
    """J_m(z) for every order and argument, (orders, z): Bessel's integral
    J_m(z) = (1/2pi) * integral exp(j*(m*tau - z*sin(tau))) dtau by the trapezoid rule over a
    full period, all orders at once by an inverse FFT (exact for this band-limited integrand
    once the nodes exceed m + |z| + 30)."""
    nodes = int(2 * (np.max(orders) + np.max(np.abs(z)) + 32))
    tau = 2 * math.pi * np.arange(nodes) / nodes
    spectrum = np.fft.ifft(np.exp(-1j * z[:, None] * np.sin(tau)[None, :]), axis=1).real
    return spectrum[:, orders].T


def terms_needed(bound: float) -> int:
    """Number of expansion terms for offset phases up to `bound` radians."""
    orders = np.arange(int(1.5 * bound) + 40)
    j = np.abs(bessel_j(orders, np.array([bound])))[:, 0]
    above = np.nonzero(j >= TOLERANCE)[0]
    return int(above[-1]) + 2 if above.size else 1


def if_cube(centre_m: np.ndarray, offsets_m: np.ndarray, speeds_mps: np.ndarray, amplitudes: np.ndarray,
            config: RadarConfig, n_samples: int) -> np.ndarray:
    """(n_chirps, n_samples) complex64 IF of scatterers at ranges centre_m[n] + offsets_m[n, i]
    moving at speeds_mps[n, i]. The centre's phase is float64; the offsets (metres from the
    centre, float32) keep 1e-7 m, a phase error below 1e-3 rad."""
    lam = C / config.carrier_hz
    slope, fs = config.slope_hz_per_s, config.sample_rate_hz
    tau_c = 2.0 * (centre_m - config.range_offset_m) / C  # (n,)
    d = offsets_m.astype(np.float32)
    # fast-time frequency: the centre's beat, plus each scatterer's beat offset and intra-chirp Doppler
    delta = (np.float32(2 * math.pi * 2 * slope / C) * d
             + np.float32(2 * math.pi * 2 / lam) * speeds_mps.astype(np.float32))
    mid = 0.5 * (delta.max(axis=1) + delta.min(axis=1))
    delta -= mid[:, None]
    omega0 = 2 * math.pi * slope * tau_c + mid.astype(np.float64)
    half = (n_samples - 1) / (2.0 * fs)  # fast time t = half * (x + 1)
    beta = delta * np.float32(half)
    # slow-time phase: carrier 4*pi*R/lambda and residual video phase -pi*S*tau^2, split into the
    # centre's (float64) and each scatterer's part
    centre_phase = np.mod(4 * math.pi * centre_m / lam - math.pi * slope * tau_c ** 2, 2 * math.pi)
    own = (np.float32(4 * math.pi / lam) * d - np.float32(math.pi * slope * 4 / C) * d
           * (tau_c.astype(np.float32)[:, None] + np.float32(1 / C) * d))
    angle = np.mod(own + beta + centre_phase.astype(np.float32)[:, None], np.float32(2 * math.pi))
    amp = amplitudes.astype(np.float32)
    a_both = np.stack([amp * np.cos(angle), amp * np.sin(angle)], axis=1)  # (n, 2, i)
    bound = float(np.max(np.abs(beta))) if beta.size else 0.0
    n_terms = terms_needed(bound) if bound > 1e-9 else 1
    u = beta / np.float32(bound) if bound > 1e-9 else np.zeros_like(beta)
    coef = np.empty((d.shape[0], 2, n_terms), dtype=np.float32)
    t_prev, t_cur, t_next = np.ones_like(u), u.copy(), np.empty_like(u)
    coef[:, :, 0] = a_both.sum(axis=2)
    for m in range(1, n_terms):
        if m > 1:  # Chebyshev recurrence T_m = 2u T_(m-1) - T_(m-2), in place
            np.multiply(u, t_cur, out=t_next)
            t_next *= 2.0
            t_next -= t_prev
            t_prev, t_cur, t_next = t_cur, t_next, t_prev
        coef[:, :, m] = np.einsum("nki,ni->nk", a_both, t_cur)
    x = np.linspace(-1.0, 1.0, n_samples)
    orders = np.arange(n_terms)
    kernel = (np.where(orders == 0, 1.0, 2.0) * (1j ** orders))[:, None] * bessel_j(orders, bound * x)
    t_k = np.arange(n_samples) / fs
    fast = np.mod(omega0[:, None] * t_k[None, :], 2 * math.pi).astype(np.float32)
    carrier = np.empty(fast.shape, dtype=np.complex64)
    carrier.real, carrier.imag = np.cos(fast), np.sin(fast)
    summed = (coef[:, 0, :] + 1j * coef[:, 1, :]).astype(np.complex64) @ kernel.astype(np.complex64)
    return carrier * summed
