"""Estimators, calibration and open set on synthetic data (no simulation)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.base import clone

from signatures.train import classifiers as clf
from signatures.classify.ensemble import MEMBERS, calibrate, weighted_vote
from signatures.classify.openset import fit_openset
from signatures.train.training import choose_cascade_threshold


def _blobs(n: int, centres: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    y = np.arange(n) % len(centres)
    return (centres[y] + rng.normal(scale=0.5, size=(n, centres.shape[1]))).astype(np.float32), y


CENTRES = np.array([[0, 0, 0, 0], [3, 0, 0, 0], [0, 3, 0, 0], [0, 0, 3, 0]], dtype=float)


def test_members_follow_the_estimator_contract() -> None:
    X, y = _blobs(400, CENTRES, 0)
    Xt, yt = _blobs(200, CENTRES, 1)
    for name in MEMBERS:
        m = clf.make_member(name, seed=0)
        clone(m)  # sklearn convention: unfitted params only
        m.fit(X, y)
        assert np.mean(m.predict(Xt) == yt) > 0.95
        p = m.predict_proba(Xt)
        assert p.shape == (200, 4) and np.allclose(p.sum(1), 1)
    assert clf.make_knn()[-1].n_neighbors == 5 and clf.make_knn()[-1].metric == "euclidean"


def test_bounded_temperature_is_sklearns_fit_inside_its_range() -> None:
    """Where the log-loss optimum lies inside `BETA_RANGE`, the bounded fit is scikit-learn's own
    temperature scaling of the same vote."""
    from sklearn.calibration import CalibratedClassifierCV
    from sklearn.ensemble import VotingClassifier
    from sklearn.frozen import FrozenEstimator

    X, y = _blobs(400, CENTRES / 3, 0)  # overlapping classes: the fit has an optimum
    Xv, yv = _blobs(200, CENTRES / 3, 2)
    members = clf.fit_members(X, y, seed=0)
    weights = [1.0, 2.0, 1.0]
    vote = VotingClassifier([(n, FrozenEstimator(m)) for n, m in members.items()], voting="soft",
                            weights=weights).fit(Xv, yv)
    ens = CalibratedClassifierCV(FrozenEstimator(vote), method="temperature").fit(Xv, yv)
    sk_beta = float(ens.calibrated_classifiers_[0].calibrators[0].beta_)
    avg = clf.soft_vote(members, Xv, weights)
    beta = clf.bounded_temperature(avg, yv)
    assert clf.BETA_RANGE[0] < sk_beta < clf.BETA_RANGE[1]
    assert beta == pytest.approx(sk_beta, rel=1e-3)
    np.testing.assert_allclose(calibrate(avg, beta), ens.predict_proba(Xv), atol=1e-3)


def test_bounded_temperature_stops_at_its_bounds() -> None:
    """A vote that is always right (the ill-posed fit runs off to certainty) stops at the upper
    bound; one that is always wrong at the lower."""
    y = np.array([0, 1, 2] * 20)
    right = np.full((60, 3), 0.1)
    right[np.arange(60), y] = 0.8
    assert clf.bounded_temperature(right, y) == pytest.approx(clf.BETA_RANGE[1])
    assert clf.bounded_temperature(right, (y + 1) % 3) == pytest.approx(clf.BETA_RANGE[0])


def test_vote_weights_come_from_the_members_validation_probabilities() -> None:
    """The weights are chosen from probabilities computed once: a member that is always right
    outweighs one that is always wrong, and the weighted vote then names every label."""
    y = np.array([0, 1, 2, 1, 0, 2, 2, 1])
    right = np.full((y.size, 3), 0.05)
    right[np.arange(y.size), y] = 0.9
    wrong = np.roll(right, 1, axis=1)
    weights = clf.vote_weights([wrong, right], y)
    assert weights[1] > weights[0]
    assert (weighted_vote([wrong, right], weights).argmax(axis=1) == y).all()
    assert np.allclose(weighted_vote([wrong, right], [0.0, 2.0]), right)  # a member of weight 0 is left out


def test_openset_rejects_an_unseen_cluster_and_keeps_known_ones() -> None:
    X, y = _blobs(800, CENTRES, 0)
    Xv, yv = _blobs(400, CENTRES, 3)
    model = fit_openset(X, y, 4, Xv, yv, yv, quantile=0.99)
    Xk, yk = _blobs(400, CENTRES, 4)
    assert model.unknown(Xk, yk).mean() < 0.05
    Xu, _ = _blobs(200, np.array([[1.5, 1.5, 0, 3.0]]), 5)  # between classes, off every manifold
    assert model.unknown(Xu, np.zeros(200, dtype=int)).mean() > 0.9
    Xk[:5, 0] = np.nan  # a return with no distance is not `known` (fail closed)
    assert model.unknown(Xk[:5], yk[:5]).all()


def test_cascade_threshold_prefers_not_running_the_cnn_when_it_does_not_help() -> None:
    y = np.array([0, 1, 0, 1])
    p_ens = np.array([[0.9, 0.1], [0.2, 0.8], [0.55, 0.45], [0.6, 0.4]])
    assert choose_cascade_threshold(p_ens, p_ens, y) == 0.0
    p_cnn = np.array([[0.9, 0.1], [0.2, 0.8], [0.9, 0.1], [0.05, 0.95]])
    assert choose_cascade_threshold(p_ens, p_cnn, y) == 0.7


def test_numpy_knn_matches_sklearn(tmp_path) -> None:
    from signatures.classify.members import KnnArrays

    X, y = _blobs(400, CENTRES, 0)
    Xt, _ = _blobs(200, CENTRES, 1)
    m = clf._fit(clf.make_knn(), X, y)
    arrays = clf.knn_arrays(m, X, y, 4)
    np.savez(tmp_path / "knn.npz", **arrays)
    np.testing.assert_allclose(KnnArrays(tmp_path / "knn.npz").predict_proba(Xt), m.predict_proba(Xt), atol=1e-6)
    # the exported references are the points the neighbour search indexed at fit time
    Zt = m[0].transform(Xt)
    dist, idx = m[-1].kneighbors(Zt, 5)
    mine = np.linalg.norm(Zt[:, None, :].astype(np.float64) - arrays["refs"][idx].astype(np.float64), axis=2)
    np.testing.assert_allclose(mine, dist, rtol=1e-5)
    with pytest.raises(ValueError, match="fitted on 400"):
        clf.knn_arrays(m, X[:10], y[:10], 4)


def test_physics_check_rejects_wrong_rotor_rates_and_abstains_when_unsure() -> None:
    from signatures.classify.openset import PHYS_FEATURES, physics_check
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


def test_openset_ships_only_its_mode_and_every_physics_parameter() -> None:
    from signatures.errors import SignaturesError
    from signatures.classify.openset import PHYS_FEATURES, OpenSet, PhysicsCheck, physics_check
    from signatures.profiles import shipped_profiles

    classes = ("m600", "m300", "phantom4", "bird", "none")
    chk = physics_check(classes, shipped_profiles(), PHYS_FEATURES, jitter=0.005, tip_bin_mps=0.2)
    X, y = _blobs(200, CENTRES, 0)
    model = fit_openset(X, y, 4, X, y, y, quantile=0.99, physics=chk, mode="physics")
    z = model.arrays()
    assert not any(k.startswith("ref_") or k in ("mean", "scale", "thresholds") for k in z)
    names = [str(n) for n in z["phys_param_names"]]
    assert set(names) == set(PhysicsCheck.SCALARS) >= {"min_rel_tol", "min_rel_tip_tol"}
    loaded = OpenSet.from_arrays(z)
    assert all(getattr(loaded.physics, n) == getattr(chk, n) for n in PhysicsCheck.SCALARS)
    np.testing.assert_array_equal(loaded.physics.flash_hz_, chk.flash_hz_)
    assert loaded.physics.rate_slips == chk.rate_slips
    with pytest.raises(SignaturesError, match="no distance test"):
        loaded.unknown(X, y, mode="distance")
    # a value the file lacks is an error, never the code default
    partial = dict(z, phys_param_names=z["phys_param_names"][:-1], phys_param_values=z["phys_param_values"][:-1])
    with pytest.raises(KeyError, match="tip_bin_mps"):
        OpenSet.from_arrays(partial)
    # the file's values win over the defaults
    tuned = dict(z, phys_param_values=np.where(z["phys_param_names"] == "min_rel_tol", 0.5, z["phys_param_values"]))
    assert OpenSet.from_arrays(tuned).physics.min_rel_tol == 0.5 != PhysicsCheck().min_rel_tol
    both = OpenSet.from_arrays(model.arrays(("physics", "distance")))
    np.testing.assert_array_equal(both.unknown(X, y, "distance"), model.unknown(X, y, "distance"))


@settings(max_examples=200, deadline=None)
@given(rows=st.integers(1, 6), n=st.integers(1, 900), k=st.integers(1, 7), levels=st.integers(1, 50),
       nan_share=st.sampled_from([0.0, 0.0, 0.01, 0.5]), seed=st.integers(0, 2**32 - 1))
def test_k_smallest_selects_what_a_full_partition_selects(rows, n, k, levels, nan_share, seed) -> None:
    """The block-minimum bound never drops a neighbour: the same k values per row as argpartition,
    with heavy ties (few levels) and NaN distances (which argpartition puts last)."""
    from signatures.classify.members import k_smallest

    k = min(k, n)
    rng = np.random.default_rng(seed)
    d = rng.integers(0, levels, size=(rows, n)).astype(np.float64)
    d += rng.normal(scale=1e-3, size=(rows, n)) * (levels > 40)
    d[rng.random((rows, n)) < nan_share] = np.nan
    got = k_smallest(d, k)
    assert got.shape == (rows, k) and all(len(set(r)) == k for r in got.tolist())
    want = np.partition(d, k - 1, axis=1)[:, :k]
    np.testing.assert_array_equal(np.sort(np.take_along_axis(d, got, axis=1), axis=1), np.sort(want, axis=1))


def test_k_smallest_sees_past_a_nan_in_a_block() -> None:
    from signatures.classify.members import k_smallest

    d = np.arange(400, dtype=float)[None, :] + 100.0
    d[0, 3], d[0, 5] = 0.5, np.nan  # the first block holds the smallest value and a NaN
    assert sorted(d[0, k_smallest(d, 3)[0]].tolist()) == [0.5, 100.0, 101.0]
