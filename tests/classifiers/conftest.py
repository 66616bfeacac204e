"""A tiny bundle trained once per test session on the stand-in features (seconds)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from signatures.profiles import load_profiles, shipped_profiles
from signatures.train.training import TrainConfig, train_bundle
from tests.classifiers.standin import standin_extract

ENROL = Path(__file__).resolve().parents[2] / "signatures" / "data" / "enrol_example.json"


def tiny_config(seed: int = 3, cnn: bool = True, extra: bool = False) -> TrainConfig:
    profiles = dict(shipped_profiles())
    if extra:
        profiles.update(load_profiles(ENROL))
    return TrainConfig(preset="paper", profiles=tuple(profiles.values()), n_train=200, n_val=100,
                       seed=seed, cnn=cnn, workers=1)


@contextmanager
def own_models(root: Path) -> Iterator[pytest.MonkeyPatch]:
    """Models and dataset cache of one test module, under `root` (a module-scoped fixture
    cannot take `monkeypatch`); the patch is yielded for more variables."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("AUTHN_MODELS_DIR", str(root / "models"))
        mp.setenv("AUTHN_CACHE_DIR", str(root / "cache"))
        yield mp


@pytest.fixture(scope="session")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("dscache")


@pytest.fixture(scope="session")
def tiny_bundle(tmp_path_factory: pytest.TempPathFactory, cache_dir: Path) -> Path:
    out = tmp_path_factory.mktemp("bundles") / "paper"
    train_bundle(tiny_config(), out, standin_extract, cache=cache_dir)
    return out
