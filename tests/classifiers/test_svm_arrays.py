"""The shipped SVM arrays (`svm.npz`) give scikit-learn's one-vs-rest SVC probabilities exactly,
in numpy: libsvm's Platt sigmoid, its clipping and its two-class coupling included."""

from __future__ import annotations

import numpy as np
import pytest

from signatures.train import classifiers as clf
from signatures.errors import SignaturesError
from signatures.classify.members import SvmArrays


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(0)
    y = rng.integers(0, 5, 400)
    X = (rng.normal(size=(400, 7)) + np.eye(5, 7)[y] * 2.0).astype(np.float32) * np.float32(30.0)
    return clf._fit(clf.make_svm(0), X, y), X


def test_svm_arrays_match_scikit_learn(fitted, tmp_path) -> None:
    model, X = fitted
    np.savez(tmp_path / "svm.npz", **clf.svm_arrays(model, 6))  # one class the SVM never saw
    svm = SvmArrays(tmp_path / "svm.npz")
    rng = np.random.default_rng(1)
    rows = np.vstack([X[:50], rng.normal(size=(50, 7)).astype(np.float32) * 30,
                      np.full((2, 7), 1e4, np.float32), np.full((1, 7), -1e4, np.float32)])  # far out: saturated
    got, want = svm.predict_proba(rows), model.predict_proba(rows)
    assert got.shape == (len(rows), 6) and np.all(got[:, 5] == 0.0)
    np.testing.assert_allclose(got[:, :5], want, atol=2e-6)  # float32 output
    np.testing.assert_allclose(got.sum(axis=1), 1.0, atol=1e-5)


def test_inconsistent_svm_arrays_are_refused(fitted, tmp_path) -> None:
    arrays = clf.svm_arrays(fitted[0], 5)
    arrays["starts"] = arrays["starts"][:-1]
    np.savez(tmp_path / "svm.npz", **arrays)
    with pytest.raises(SignaturesError, match="inconsistent SVM arrays"):
        SvmArrays(tmp_path / "svm.npz")
