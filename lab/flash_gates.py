"""Realistic blade-flash gates for the flash estimators: the exact `flash_series.flash_series_batch`
inputs that `features.extract` computes for simulated dataset scenes (all airframes, birds,
noise only; hovering and moving; SNR -5..30 dB). Shared by the estimator tests
(tests/features/test_batch_estimators.py) and the benchmark (benchmarks/test_bench_batch_estimators.py),
which import no test module."""

from __future__ import annotations

from dataclasses import dataclass
from unittest import mock

import numpy as np

from signatures.dsp import flash_series
from signatures.train.dataset import DatasetSpec, draw_scene
from signatures.features import extract
from signatures.profiles import shipped_profiles
from signatures.radar import RadarConfig
from signatures.sim.simulate import simulate


@dataclass(frozen=True)
class Gate:
    """What the extraction passes to `flash_series.flash_series_batch` for one return (its row)."""

    slow: np.ndarray  # complex64 (chirps, bins)
    config: RadarConfig
    body_hz: float
    range_bin_m: float
    n_fft: int
    label: str
    snr_db: float


def simulated_gates(preset: str, n: int, seed: int = 0) -> list[Gate]:
    """Gates of dataset scenes 0..n-1 of `preset` (classes cycle: m300, m600, phantom4, bird, none)."""
    spec = DatasetSpec(preset=preset, profiles=tuple(shipped_profiles().values()), split="test", n=n, seed=seed)
    gates: list[Gate] = []
    for i in range(n):
        scene, sim_seed = draw_scene(spec, i)
        rec, _ = simulate(scene, spec.waveform, seed=sim_seed)
        seen: list[tuple] = []

        def capture(slow, config, body_hz, range_bin_m, n_fft, _seen=seen, _real=flash_series.flash_series_batch):
            _seen.append((np.array(slow[0]), config, float(body_hz[0]), range_bin_m, n_fft))
            return _real(slow, config, body_hz, range_bin_m, n_fft)

        with mock.patch.object(flash_series, "flash_series_batch", capture):
            extract(rec)
        slow, config, body_hz, bin_m, n_fft = seen[0]
        gates.append(Gate(slow, config, float(body_hz), float(bin_m), int(n_fft), scene.label, scene.snr_db))
    return gates
