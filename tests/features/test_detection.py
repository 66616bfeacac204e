"""CFAR over range: silent on empty scenes, detects UAVs from -10 dB SNR up."""

from __future__ import annotations

import pytest

from signatures.features import extract
from tests.features.conftest import sim

N_EMPTY = 30


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_no_detection_on_empty_scenes(preset):
    """`none` scenes, half with 20-40 dB ground clutter: the false detection rate is reported."""
    false = 0
    for seed in range(N_EMPTY):
        clutter = None if seed % 2 else 20.0 + seed % 21
        rec, _ = sim(kind="none", model=None, preset=preset, seed=seed, clutter_db=clutter)
        false += extract(rec).detected
    print(f"{preset}: {false}/{N_EMPTY} empty scenes with a detection")
    assert false == 0


@pytest.mark.parametrize("preset", ["paper", "wide"])
@pytest.mark.parametrize("snr_db", [-10.0, 0.0])
def test_detects_uavs(preset, snr_db):
    models = ("m600", "m300", "phantom4")
    hits = 0
    for seed in range(9):
        rec, truth = sim(model=models[seed % 3], preset=preset, seed=100 + seed, snr_db=snr_db,
                         radial_speed_mps=0.0 if seed % 2 else 7.0, clutter_db=10.0)
        res = extract(rec)
        hits += res.detected and abs(res.range_m - truth.range_m) <= rec.config.range_bin_m(rec.n_samples)
    assert hits == 9
