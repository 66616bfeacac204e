"""Datasets: reproducible, split by grid block and seed, cached without pickle."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from signatures.train.dataset import (BLOCK_M, Dataset, DatasetError, DatasetSpec, block_split, draw_scene,
                                      feature_version, generate)
from signatures.profiles import shipped_profiles
from tests.classifiers.standin import standin_extract

PROFILES = tuple(shipped_profiles().values())


def _spec(split: str = "train", n: int = 60, seed: int = 0, **kw) -> DatasetSpec:
    return DatasetSpec(preset="paper", profiles=PROFILES, split=split, n=n, seed=seed, **kw)


#: Scenes 0-4, 11 and 13 of `_spec()`: (label, range, elevation, speed, SNR, clutter, simulator seed). The
#: shipped models were trained on these draws: a change to the sampler must not move them (or must
#: bump GENERATOR_VERSION and retrain).
PINNED_SCENES = {
    0: ("m600", 398.622629, 13.0485991, 0.0, -2.05689879, None, 1249653144719271898),
    1: ("m300", 1098.99955, 15.3001966, 2.0, 10.7902402, None, 8674433634896469815),
    2: ("phantom4", 734.370479, -25.8328593, -10.0, 15.7838927, None, 5387735597491253290),
    3: ("bird", 1163.87285, 22.7456021, 2.0, 18.0202109, None, 8250137298836933865),
    4: ("none", 1194.06867, 53.5112712, 0.0, 27.9414563, None, 9049679738101778492),
    11: ("m300", 922.171351, -42.2468603, 0.0, 16.6317351, 5.7529632, 7849704485868173084),
    13: ("bird", 1142.84732, 55.3365541, 10.0, 27.0751463, 2.09408887, 7373817058141629911),
}


def test_scene_draws_are_pinned() -> None:
    for i, (label, r, el, v, snr, clutter, seed) in PINNED_SCENES.items():
        sc, s = draw_scene(_spec(), i)
        assert (sc.label, sc.radial_speed_mps, s) == (label, v, seed)
        assert sc.range_m == pytest.approx(r, rel=1e-8) and sc.elevation_deg == pytest.approx(el, rel=1e-8)
        assert sc.snr_db == pytest.approx(snr, rel=1e-8)
        assert sc.clutter_db == (None if clutter is None else pytest.approx(clutter, rel=1e-8))
    bird = draw_scene(_spec(), 3)[0].bird
    wing_flap = (bird.wing_length_m, bird.flap_rate_hz, bird.flap_amplitude_deg)
    assert wing_flap == pytest.approx((0.371099, 9.45707, 24.9879), rel=1e-5)


def test_cache_key_names_versions_and_code(monkeypatch) -> None:
    """The featurizer's key part follows its name, FEATURE_VERSION, SIMULATOR_VERSION and the
    digest of the code the samples come from."""
    from signatures.train import code_digest
    from signatures import features
    from signatures.sim import simulate

    base = feature_version(features.extract)
    assert feature_version(features.extract) == base and feature_version(standin_extract) != base
    monkeypatch.setattr(features, "FEATURE_VERSION", features.FEATURE_VERSION + "-next")
    bumped = feature_version(features.extract)
    monkeypatch.setattr(simulate, "SIMULATOR_VERSION", simulate.SIMULATOR_VERSION + "-next")
    resimulated = feature_version(features.extract)
    monkeypatch.setattr(code_digest, "_digest", lambda roots, packages: "other code")
    assert len({base, bumped, resimulated, feature_version(features.extract)}) == 4


def test_cache_key_digests_the_sample_code() -> None:
    """The digest reaches the estimators (imported by the featurizer), the simulator and the sampler."""
    from signatures.train import dataset
    from signatures import features
    from signatures.train.code_digest import modules_reached

    reached = modules_reached((features.extract.__module__, *dataset.SAMPLE_CODE))
    assert {"signatures.dsp.flash_series", "signatures.dsp.flash_period", "signatures.dsp.rd",
            "signatures.dsp.timefreq", "signatures.sim.simulate", "signatures.sim.sampling", "signatures.sim.scene",
            "signatures.train.dataset"} <= set(reached)


def test_split_is_a_property_of_the_block() -> None:
    rng = np.random.default_rng(0)
    for _ in range(200):
        x, y, z = rng.integers(-100, 100, 3) * 10.0
        bx, by, bz = (np.floor((c + 1000) / BLOCK_M) * BLOCK_M - 1000 for c in (x, y, z))
        assert block_split(x, y, z) == block_split(bx, by, bz) == block_split(bx + 90, by + 90, bz + 90)
    counts = Counter(block_split(x, y, z) for x in range(-1000, 1000, 100) for y in range(-1000, 1000, 100)
                     for z in range(-1000, 1000, 100))
    assert 0.6 < counts["train"] / 8000 < 0.8 and counts["val"] > 500 and counts["test"] > 1000


def test_scenes_are_reproducible_and_splits_do_not_share_seeds() -> None:
    a = [draw_scene(_spec(), i) for i in range(20)]
    b = [draw_scene(_spec(), i) for i in range(20)]
    assert a == b
    seeds = {s for _, s in a}
    assert not seeds & {s for _, s in (draw_scene(_spec("test"), i) for i in range(20))}
    assert not seeds & {s for _, s in (draw_scene(_spec(seed=1), i) for i in range(20))}
    assert Counter(sc.label for sc, _ in a) == {c: 4 for c in ("m600", "m300", "phantom4", "bird", "none")}
    for sc, _ in a:
        assert 20 <= sc.range_m <= 1200 and abs(sc.elevation_deg) <= 60.0 + 1e-9


def test_generation_is_independent_of_workers_and_cached(tmp_path: Path) -> None:
    spec = _spec(n=30, snr_db=10.0)
    one = generate(spec, standin_extract, workers=1, chunk=7, cache=tmp_path)
    two = generate(spec, standin_extract, workers=2, chunk=11, cache=False)
    np.testing.assert_array_equal(one.X, two.X)
    files = list(tmp_path.glob("*.npz"))
    assert len(files) == 1
    with np.load(files[0], allow_pickle=False) as z:  # no object arrays: loads without pickle
        assert z["X"].shape == (30, len(one.feature_names))
    again = Dataset.load(files[0])
    np.testing.assert_array_equal(again.X, one.X)
    assert list(again.y) == list(one.y) and np.all(again.snr_db == 10.0)


def test_bad_specs_are_refused() -> None:
    with pytest.raises(DatasetError):
        _spec(split="holdout")
    with pytest.raises(DatasetError):
        _spec(n=0)
