"""Estimators, calibration and open set on synthetic data (no simulation)."""

from __future__ import annotations

import numpy as np
from sklearn.base import clone

from signatures import classifiers as clf
from signatures.openset import fit_openset
from signatures.training import choose_cascade_threshold


def _blobs(n: int, centres: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    y = np.arange(n) % len(centres)
    return (centres[y] + rng.normal(scale=0.5, size=(n, centres.shape[1]))).astype(np.float32), y


CENTRES = np.array([[0, 0, 0, 0], [3, 0, 0, 0], [0, 3, 0, 0], [0, 0, 3, 0]], dtype=float)


def test_members_follow_the_estimator_contract() -> None:
    X, y = _blobs(400, CENTRES, 0)
    Xt, yt = _blobs(200, CENTRES, 1)
    for name in clf.MEMBERS:
        m = clf.make_member(name, seed=0)
        clone(m)  # sklearn convention: unfitted params only
        m.fit(X, y)
        assert np.mean(m.predict(Xt) == yt) > 0.95
        p = m.predict_proba(Xt)
        assert p.shape == (200, 4) and np.allclose(p.sum(1), 1)
    assert clf.make_knn()[-1].n_neighbors == 5 and clf.make_knn()[-1].metric == "euclidean"


def test_calibration_matches_sklearn() -> None:
    X, y = _blobs(400, CENTRES, 0)
    Xv, yv = _blobs(200, CENTRES, 2)
    members = clf.fit_members(X, y, seed=0)
    ens = clf.calibrated_ensemble(members, Xv, yv, [1.0, 2.0, 1.0])
    avg = sum(w * m.predict_proba(Xv) for w, m in zip((1, 2, 1), members.values())) / 4
    np.testing.assert_allclose(clf.calibrate(avg, clf.temperature_beta(ens)), ens.predict_proba(Xv), atol=1e-6)


def test_openset_rejects_an_unseen_cluster_and_keeps_known_ones() -> None:
    X, y = _blobs(800, CENTRES, 0)
    Xv, yv = _blobs(400, CENTRES, 3)
    model = fit_openset(X, y, 4, Xv, yv, yv, quantile=0.99)
    Xk, yk = _blobs(400, CENTRES, 4)
    assert model.unknown(Xk, yk).mean() < 0.05
    Xu, _ = _blobs(200, np.array([[1.5, 1.5, 0, 3.0]]), 5)  # between classes, off every manifold
    assert model.unknown(Xu, np.zeros(200, dtype=int)).mean() > 0.9


def test_cascade_threshold_prefers_not_running_the_cnn_when_it_does_not_help() -> None:
    y = np.array([0, 1, 0, 1])
    p_ens = np.array([[0.9, 0.1], [0.2, 0.8], [0.55, 0.45], [0.6, 0.4]])
    assert choose_cascade_threshold(p_ens, p_ens, y) == 0.0
    p_cnn = np.array([[0.9, 0.1], [0.2, 0.8], [0.9, 0.1], [0.05, 0.95]])
    assert choose_cascade_threshold(p_ens, p_cnn, y) == 0.7


def test_numpy_knn_matches_sklearn(tmp_path) -> None:
    from signatures.inference import KnnArrays

    X, y = _blobs(400, CENTRES, 0)
    Xt, _ = _blobs(200, CENTRES, 1)
    m = clf._fit(clf.make_knn(), X, y)
    np.savez(tmp_path / "knn.npz", **clf.knn_arrays(m, 4))
    np.testing.assert_allclose(KnnArrays(tmp_path / "knn.npz").proba(Xt), m.predict_proba(Xt), atol=1e-6)


def test_physics_check_rejects_wrong_rotor_rates_and_abstains_when_unsure() -> None:
    from signatures.openset import PHYS_FEATURES, physics_check
    from signatures.profiles import shipped_profiles

    prof = shipped_profiles()
    classes = ("m600", "m300", "phantom4", "bird", "none")
    names = PHYS_FEATURES
    chk = physics_check(classes, prof, names, jitter=0.005, tip_bin_mps=0.2)

    def row(rate, std, score=3.0, tip=0.0, tip_std=0.0, aliased=1.0):
        return [rate, std, score, tip, tip_std, aliased]

    F = prof["m300"].blade_flash_rate_hz  # 80 Hz
    X = np.array([row(F * 1.005, 0.2), row(F * 1.25, 0.2), row(F * 1.25, 5.0), row(0.0, 0.0), row(F * 1.25, 0.2, 0.0),
                  row(F, 0.2, tip=prof["m300"].tip_speed_mps * 1.2, aliased=0.0)])
    bad, checked = chk.verdict(X, np.array([1] * len(X)))
    assert bad.tolist() == [False, True, False, False, False, True]
    assert checked.tolist() == [True, True, False, False, False, True]
    # bird / none are classes: never unknown through this check
    bad, checked = chk.verdict(X[:2], np.array([3, 4]))
    assert not bad.any() and not checked.any()
