"""The held-out bird as point scatterers (docs/signal-model.md, "Held-out model").

Independent of the training simulator's bird (two rigid line wings, a sinusoidal flap): here
each wing is 5-7 point stations along a swept span, the stroke is asymmetric (a faster
downstroke: the flap angle carries a second harmonic), the wing folds by 10-30 % of its span
on the upstroke, and the body heaves against the stroke. Each station has a specular lobe
around broadside, like the held-out blades. The flap rate drifts by up to 3 % over the dwell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lab.heldout.airframe import Points, line_of_sight_in_body
from signatures.sim.scene import BirdParams, Scene


@dataclass(frozen=True)
class BirdTruth:
    flap_rate_hz: float  # mean over the dwell
    wing_to_body_db: float
    n_points: int


def bird_points(scene: Scene, t: np.ndarray, wavelength: float,
                rng: np.random.Generator) -> tuple[Points, BirdTruth]:
    """Body and wing stations of the scene's bird over the dwell (n_chirps, points)."""
    b = scene.bird or BirdParams()
    w, _, _, _ = line_of_sight_in_body(scene, t, rng)
    drift = rng.uniform(-0.03, 0.03)
    rate = b.flap_rate_hz * (1.0 + drift * t / max(float(t[-1]), 1e-9))
    phi = 2 * math.pi * np.cumsum(np.concatenate([[0.0], rate[:-1] * np.diff(t)])) + rng.uniform(0, 2 * math.pi)
    amp = math.radians(b.flap_amplitude_deg)
    psi = amp * (np.sin(phi) + rng.uniform(0.15, 0.35) * np.sin(2 * phi)) / 1.2  # asymmetric stroke
    upstroke = np.maximum(0.0, np.cos(phi))  # rising wing folds
    fold = 1.0 - rng.uniform(0.1, 0.3) * upstroke
    n_st = int(rng.integers(5, 8))
    rho = b.wing_length_m * (np.arange(n_st) + 0.5) / n_st
    sweep = rng.uniform(0.05, 0.2)
    heave = -rng.uniform(0.05, 0.12) * b.wing_length_m * np.sin(phi)
    along, norm_sq, amps = [np.zeros((t.size, 1))], [np.zeros((t.size, 1))], []
    body_pos = np.stack([np.zeros_like(t), np.zeros_like(t), heave], axis=1)  # (n, 3)
    along[0] = np.sum(w * body_pos, axis=1)[:, None]
    norm_sq[0] = (heave ** 2)[:, None]
    amps.append(np.ones((t.size, 1)))
    lobe = 0.3 * wavelength / (b.wing_length_m / n_st)
    floor = rng.uniform(0.1, 0.3)
    for side in (1.0, -1.0):
        r = rho[None, :] * fold[:, None]  # (n, st)
        x = -sweep * r
        y = side * (0.04 + r * np.cos(psi)[:, None])
        z = heave[:, None] + r * np.sin(psi)[:, None]
        along.append(w[:, 0:1] * x + w[:, 1:2] * y + w[:, 2:3] * z)
        norm_sq.append(x ** 2 + y ** 2 + z ** 2)
        span_dir = w[:, 1:2] * side * np.cos(psi)[:, None] + w[:, 2:3] * np.sin(psi)[:, None]
        amps.append((floor + (1 - floor) * np.exp(-(span_dir / lobe) ** 2)) * (rho / b.wing_length_m) ** 0.5)
    body_amp = amps[0]
    wings = np.concatenate(amps[1:], axis=1)
    ratio_db = scene.blade_to_body_db if scene.blade_to_body_db is not None else float(rng.uniform(-8.0, -2.0))
    k = math.sqrt(float(np.mean(body_amp ** 2)) / float(np.mean(np.sum(wings ** 2, axis=1))) * 10 ** (ratio_db / 10))
    pts = Points(np.concatenate(along, axis=1).astype(np.float32), np.concatenate(norm_sq, axis=1).astype(np.float32),
                 np.concatenate([body_amp, k * wings], axis=1).astype(np.float32))
    return pts, BirdTruth(float(np.mean(rate)), ratio_db, int(pts.amplitude.shape[1]))
