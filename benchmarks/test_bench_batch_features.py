"""Batched feature extraction (`signatures.batch_features.extract_batch`): time per return
against batch size, both presets, beside the FFT floor of one return
(`authn.bench.perf.fft_floor`).

    python -m pytest benchmarks/test_bench_batch_features.py --benchmark-enable \
        --benchmark-json=batch.json   # extra_info: ms_per_return, fft_floor_ms, x_floor
"""

from __future__ import annotations

import numpy as np
import pytest

from authn.bench.perf import fft_floor
from signatures.batch_features import extract_batch
from signatures.dataset import DatasetSpec, draw_scene
from signatures.profiles import shipped_profiles
from signatures.simulate import simulate

SIZES = {"paper": (1, 8, 64, 256), "wide": (1, 8, 32, 64)}


def _batch(preset: str, rows: int):
    """`rows` dataset returns (UAVs, birds, empty scenes; cycling 16 draws) under one configuration."""
    spec = DatasetSpec(preset, tuple(shipped_profiles().values()), "test", 16)
    recs = []
    for i in range(min(rows, 16)):
        scene, seed = draw_scene(spec, i)
        recs.append(simulate(scene, spec.waveform, seed=seed)[0])
    return np.stack([recs[i % len(recs)].iq for i in range(rows)]), recs[0].config


@pytest.mark.parametrize("preset,rows", [(p, b) for p, sizes in SIZES.items() for b in sizes])
def test_extract_batch(benchmark, preset, rows):
    iq, config = _batch(preset, rows)
    benchmark.group = f"batch features {preset}"
    benchmark.extra_info["rows"] = rows
    results = benchmark(extract_batch, iq, config)
    assert len(results) == rows
    if benchmark.stats:  # None with --benchmark-disable
        per_return = benchmark.stats.stats.median * 1e3 / rows
        floor = fft_floor(preset)["fft_ms"]
        benchmark.extra_info.update(ms_per_return=round(per_return, 3), fft_floor_ms=round(floor, 3),
                                    x_floor=round(per_return / floor, 2))
