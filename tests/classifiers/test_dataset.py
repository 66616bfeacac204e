"""Datasets: reproducible, split by grid block and seed, cached without pickle."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from signatures.dataset import BLOCK_M, Dataset, DatasetError, DatasetSpec, block_split, draw_scene, generate
from signatures.profiles import shipped_profiles
from tests.classifiers.standin import standin_extract

PROFILES = tuple(shipped_profiles().values())


def _spec(split: str = "train", n: int = 60, seed: int = 0, **kw) -> DatasetSpec:
    return DatasetSpec(preset="paper", profiles=PROFILES, split=split, n=n, seed=seed, **kw)




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
