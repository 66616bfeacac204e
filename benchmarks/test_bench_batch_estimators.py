"""Blade-flash estimators (flash series + periodicity + rotor count) per batch of gates
(`signatures.dsp.flash_series`, `signatures.dsp.flash_period`), per batch size and preset.

    python -m pytest benchmarks/test_bench_batch_estimators.py --benchmark-enable

Per-return time is the reported time / B (the group names carry B). The gates are distinct
simulated dataset scenes (lab/flash_gates.py; ~10 s to simulate), as many as the
largest batch, so the batches hold the realistic spread of event counts.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from signatures.dsp.flash_period import periodicity_batch
from signatures.dsp.flash_series import flash_series_batch
from lab.flash_gates import simulated_gates

pytestmark = pytest.mark.slow  # ~18 s to simulate the gates of both presets

SIZES = {"paper": (1, 8, 64, 256), "wide": (1, 8, 64)}
CASES = [(p, b) for p, sizes in SIZES.items() for b in sizes]


@functools.cache
def _gates(preset: str) -> tuple:
    found = simulated_gates(preset, int(max(SIZES[preset]) * 1.1))
    return preset, [g for g in found if g.slow.shape[1] == 3]


@pytest.fixture
def gates(request):  # request.param: the preset (parametrized indirectly with its batch sizes, CASES)
    return _gates(request.param)  # simulated once per preset and process


def _batch(gates, size: int):
    picks = [gates[i % len(gates)] for i in range(size)]
    return np.stack([g.slow for g in picks]), np.array([g.body_hz for g in picks]), picks[0]


@pytest.mark.parametrize(("gates", "size"), CASES, indirect=["gates"])
def test_flash_estimators(benchmark, gates, size: int) -> None:
    preset, found = gates
    slow, body, g = _batch(found, size)
    benchmark.group = f"flash estimators {preset} B={size}"
    benchmark.extra_info["returns"] = size  # per-return time = time / returns (--benchmark-json keeps it)

    def batched():
        return periodicity_batch(flash_series_batch(slow, g.config, body, g.range_bin_m, g.n_fft))

    result = benchmark(batched)
    assert len(result.n_events) == size
