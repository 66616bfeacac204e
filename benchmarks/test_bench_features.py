"""Feature extraction per return, gated (slow-time work on the target's range gate only)
versus full cube (Doppler map and STFT of every range bin first), both presets.

    python -m pytest benchmarks/test_bench_features.py --benchmark-enable
"""

from __future__ import annotations

import pytest

from lab.bench.pareto import extract_full_cube
from signatures.features import extract
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate


@pytest.fixture(scope="module", params=["paper", "wide"])
def rec(request):
    scene = Scene(profile=shipped_profiles()["m300"], range_m=500.0, radial_speed_mps=5.0, snr_db=10.0,
                  clutter_db=20.0)
    return simulate(scene, get_preset(request.param), seed=7)[0]


@pytest.mark.parametrize("full_cube", [False, True], ids=["gated", "full"])
def test_extract(benchmark, rec, full_cube):
    benchmark.group = f"features {rec.n_chirps}x{rec.n_samples}"
    res = benchmark(extract_full_cube if full_cube else extract, rec)
    assert res.detected
