"""Batched feature extraction (`signatures.dsp.extraction.extract_batch`): time per return
against batch size, both presets, both FFT backends, the whole extraction and its cube stage
(scaling, clutter suppression, range FFT, profile, detection, gating) alone, beside the FFT
floor of one return (`lab.bench.perf.fft_floor`).

    python -m pytest benchmarks/test_bench_batch_features.py --benchmark-enable \
        --benchmark-json=batch.json   # extra_info: ms_per_return, fft_floor_ms, x_floor
"""

from __future__ import annotations

import numpy as np
import pytest

from lab.bench.perf import fft_floor
from signatures.dsp import extraction as bf
from signatures.train.dataset import DatasetSpec, draw_scene
from signatures.profiles import shipped_profiles
from signatures.sim.simulate import simulate

SIZES = {"paper": (1, 8, 64, 256), "wide": (1, 8, 32, 64)}


def _batch(preset: str, rows: int):
    """`rows` dataset returns (UAVs, birds, empty scenes; cycling 16 draws) under one configuration."""
    spec = DatasetSpec(preset, tuple(shipped_profiles().values()), "test", 16)
    recs = []
    for i in range(min(rows, 16)):
        scene, seed = draw_scene(spec, i)
        recs.append(simulate(scene, spec.waveform, seed=seed)[0])
    return np.stack([recs[i % len(recs)].iq for i in range(rows)]), recs[0].config


#: The `wide` batches of 32 and 64 take 1-3 s each (~17 s together): slow, so the quick loop keeps the rest.
CASES = [pytest.param(p, b, backend, marks=[pytest.mark.slow] if p == "wide" and b >= 32 else [])
         for p, sizes in SIZES.items() for b in sizes for backend in ("numpy", "scipy")]


@pytest.mark.parametrize("preset,rows,backend", CASES)
def test_extract_batch(benchmark, preset, rows, backend):
    iq, config = _batch(preset, rows)
    benchmark.group = f"batch features {preset}"
    results = benchmark(bf.extract_batch, iq, config, fft_backend=backend)
    assert len(results) == rows
    _per_return(benchmark, preset, rows)


@pytest.mark.parametrize("preset,rows,backend", CASES)
def test_cube_stage(benchmark, preset, rows, backend):
    iq, _ = _batch(preset, rows)
    benchmark.group = f"batch cube stage {preset}"
    cube = benchmark(bf._cube_stage, iq, [None] * rows, 5, True, "if", list(range(rows)), backend)
    assert cube.slow.shape[0] == rows
    _per_return(benchmark, preset, rows)


def _per_return(benchmark, preset: str, rows: int) -> None:
    benchmark.extra_info["rows"] = rows
    if benchmark.stats:  # None with --benchmark-disable
        per_return = benchmark.stats.stats.median * 1e3 / rows
        floor = fft_floor(preset)["fft_ms"]
        benchmark.extra_info.update(ms_per_return=round(per_return, 3), fft_floor_ms=round(floor, 3),
                                    x_floor=round(per_return / floor, 2))
