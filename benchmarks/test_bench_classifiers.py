"""Single-return inference latency of the shipped bundles (features excluded).

Run: python -m pytest benchmarks/test_bench_classifiers.py --benchmark-enable
"""

from __future__ import annotations

import numpy as np
import pytest

from signatures.classify.inference import bundle_dir, load_classifier

PRESETS = [p for p in ("paper", "wide") if (bundle_dir(p) / "card.json").is_file()]
NO_BUNDLE = pytest.param("none", marks=pytest.mark.skip(reason="no trained classifier bundle (authn models train)"))


@pytest.fixture(scope="module", params=PRESETS or [NO_BUNDLE])
def model(request: pytest.FixtureRequest):
    clf = load_classifier(request.param)
    rng = np.random.default_rng(0)
    x = rng.normal(size=clf.n_features)
    rd = rng.normal(size=tuple(clf.card["cnn"]["shape"]) if clf.has_cnn else (32, 32))
    return clf, x.astype(np.float32)[None], rd.astype(np.float32)


@pytest.mark.parametrize("member", ["knn", "rf", "svm"])
def test_member(benchmark, model, member: str) -> None:
    clf, x, _ = model
    benchmark(clf.member_proba, member, x)


def test_ensemble(benchmark, model) -> None:
    clf, x, _ = model
    benchmark(clf.ensemble_proba, x)


def test_cnn(benchmark, model) -> None:
    clf, x, rd = model
    if not clf.has_cnn:
        pytest.skip(f"the {clf.preset} bundle has no CNN member")
    benchmark(clf.cnn_proba, rd[None])


def test_full_prediction(benchmark, model) -> None:
    """Ensemble + operational state + open-set check (+ CNN when unsure): what `authn check` pays."""
    clf, x, rd = model
    benchmark(clf.predict, x[0], rd)
