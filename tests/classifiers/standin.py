"""A small stand-in feature extractor so the classifier pipeline is tested in isolation.

It mimics the shape of `signatures.features.extract` (named float32 vector, RD patch)
without depending on that module's numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FEATURE_NAMES = ("centroid", "bandwidth", "entropy", "par", "wide_energy", "cep_q", "cep_peak", "peak_db")


@dataclass
class StandinResult:
    values: np.ndarray
    rd_patch: np.ndarray
    names: tuple[str, ...] = FEATURE_NAMES

    def as_array(self) -> np.ndarray:
        return self.values


def standin_extract(rec, expected_range_m=None) -> StandinResult:
    iq = rec.iq.astype(np.complex64)
    rp = np.fft.fft(iq * np.hanning(iq.shape[1]).astype(np.float32), axis=1)
    k = int(np.argmax(np.mean(np.abs(rp) ** 2, axis=0)))
    slow = rp[:, k] - rp[:, k].mean()
    spec = np.abs(np.fft.fftshift(np.fft.fft(slow * np.hanning(len(slow))))) ** 2 + 1e-12
    p = spec / spec.sum()
    f = np.linspace(-0.5, 0.5, len(p), endpoint=False)
    c = float(np.sum(f * p))
    bw = float(np.sqrt(np.sum((f - c) ** 2 * p)))
    ent = float(-np.sum(p * np.log(p)) / np.log(len(p)))
    par = float(np.log10(spec.max() / spec.mean()))
    core = np.abs(f - f[np.argmax(p)]) < 0.02
    wide = float(1 - p[core].sum())
    env = np.abs(slow) ** 2
    cep = np.abs(np.fft.rfft(env - env.mean()))
    q = int(np.argmax(cep[2:])) + 2
    rd = np.abs(np.fft.fftshift(np.fft.fft(rp, axis=0), axes=0)) ** 2
    j = int(np.argmax(rd[:, k]))
    rows = (np.arange(32) - 16 + j) % rd.shape[0]
    cols = np.clip(np.arange(32) - 16 + k, 0, rd.shape[1] - 1)
    patch = 10 * np.log10(rd[np.ix_(rows, cols)] + 1e-12)
    patch = (patch - patch.max()) / 60.0
    vals = np.array([c, bw, ent, par, wide, q / len(env), float(cep[q] / (cep.sum() + 1e-12)),
                     10 * np.log10(spec.max())], dtype=np.float32)
    return StandinResult(vals, patch.astype(np.float32))
