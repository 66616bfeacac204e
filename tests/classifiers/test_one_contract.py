"""Inference through one implementation: every model of a bundle answers scikit-learn's
`predict_proba` contract, the numpy members equal the fitted scikit-learn estimators they were
exported from, the soft vote and its temperature are the ones training uses, and the shipped
bundles answer exactly what they answered before (`data/shipped_outputs.npz`)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from signatures.train import classifiers as clf
from signatures.classify.ensemble import MEMBERS, SoftVote, Temperature
from signatures.errors import SignaturesError
from signatures.classify.inference import Classifier, load_classifier
from signatures.classify.members import load_member
from signatures.classify.modelcard import read_card, write_card

#: The shipped bundles' outputs on 40 simulated returns each, recorded with the code before the
#: members shared this contract (features, 8 RD patches, every member, the ensemble, the CNN, the
#: state head and `predict_many`'s labels, confidences and states).
SHIPPED = Path(__file__).parent / "data" / "shipped_outputs.npz"
CENTRES = np.array([[0, 0, 0, 0], [2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0]], dtype=float)


def _blobs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    y = np.arange(n) % len(CENTRES)
    return (CENTRES[y] + rng.normal(scale=0.7, size=(n, 4))).astype(np.float32), y


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, dict, np.ndarray, np.ndarray]:
    """scikit-learn members fitted on overlapping blobs, and the numpy members read from their arrays."""
    X, y = _blobs(400, 0)
    sk = clf.fit_members(X, y, seed=0)
    sk["rf_state"] = clf.fit_state_head(X, (y % 2).astype(bool), seed=0)
    folder = tmp_path_factory.mktemp("members")
    arrays = {"knn": clf.knn_arrays(sk["knn"], X, y, 4), "rf": clf.forest_arrays(sk["rf"], 4),
              "svm": clf.svm_arrays(sk["svm"], 4), "rf_state": clf.forest_arrays(sk["rf_state"], 2)}
    ours = {}
    for name, a in arrays.items():
        np.savez(folder / f"{name}.npz", **a)
        ours[name] = load_member(folder / f"{name}.npz")
    Xv, yv = _blobs(300, 1)
    return sk, ours, Xv, yv


@pytest.mark.parametrize("name", [*MEMBERS, "rf_state"])
def test_each_numpy_member_answers_what_its_scikit_learn_estimator_answers(fitted, name: str) -> None:
    sk, ours, Xv, _ = fitted
    np.testing.assert_array_equal(ours[name].classes_, sk[name].classes_)
    got, want = ours[name].predict_proba(Xv), sk[name].predict_proba(Xv)
    assert got.shape == want.shape == (len(Xv), len(sk[name].classes_))
    np.testing.assert_allclose(got, want, atol=2e-6)  # float32 outputs


def test_the_soft_vote_is_scikit_learns_voting_classifier_and_trainings_vote(fitted) -> None:
    from sklearn.ensemble import VotingClassifier
    from sklearn.frozen import FrozenEstimator

    sk, ours, Xv, yv = fitted
    weights = [1.0, 2.0, 1.0]
    vote = VotingClassifier([(m, FrozenEstimator(sk[m])) for m in MEMBERS], voting="soft", weights=weights)
    want = vote.fit(Xv, yv).predict_proba(Xv)
    numpy_vote = SoftVote([ours[m] for m in MEMBERS], weights)
    np.testing.assert_array_equal(numpy_vote.classes_, vote.classes_)
    np.testing.assert_allclose(numpy_vote.predict_proba(Xv), want, atol=2e-6)
    # training's vote (what the weights and the temperature are chosen on) is the same code
    np.testing.assert_allclose(clf.soft_vote({m: sk[m] for m in MEMBERS}, Xv, weights), want, atol=1e-12)


def test_the_temperature_is_scikit_learns_calibrated_classifier_map(fitted) -> None:
    from sklearn.calibration import CalibratedClassifierCV
    from sklearn.ensemble import VotingClassifier
    from sklearn.frozen import FrozenEstimator

    sk, ours, Xv, yv = fitted
    weights = [1.0, 1.0, 1.0]
    vote = VotingClassifier([(m, FrozenEstimator(sk[m])) for m in MEMBERS], voting="soft",
                            weights=weights).fit(Xv, yv)
    cal = CalibratedClassifierCV(FrozenEstimator(vote), method="temperature").fit(Xv, yv)
    beta = float(cal.calibrated_classifiers_[0].calibrators[0].beta_)
    ours_cal = Temperature(SoftVote([ours[m] for m in MEMBERS], weights), beta)
    np.testing.assert_array_equal(ours_cal.classes_, cal.classes_)
    # scikit-learn adds float64's eps before the log, the bundle 1e-12: they part only where p ~ 0
    np.testing.assert_allclose(ours_cal.predict_proba(Xv), cal.predict_proba(Xv), atol=1e-4)


def test_a_member_of_weight_zero_is_never_run() -> None:
    class Fixed:
        classes_ = np.arange(2)

        def predict_proba(self, X):
            return np.tile([0.25, 0.75], (len(X), 1))

    vote = SoftVote([Fixed(), None], [2.0, 0.0])
    np.testing.assert_array_equal(vote.predict_proba(np.zeros((3, 1))), np.tile([0.25, 0.75], (3, 1)))
    with pytest.raises(ValueError, match="missing"):
        SoftVote([None, Fixed()], [1.0, 1.0])


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_the_shipped_bundles_answer_as_before(preset: str) -> None:
    with np.load(SHIPPED, allow_pickle=False) as z:
        before = {k.removeprefix(f"{preset}_"): z[k] for k in z.files if k.startswith(f"{preset}_")}
    c = load_classifier(preset)
    X = before["X"]
    for m in MEMBERS:
        np.testing.assert_allclose(c.member_proba(m, X), before[m], rtol=0, atol=1e-6)
    np.testing.assert_allclose(c.ensemble_proba(X), before["ensemble"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(c.cnn_proba(before["rd"]), before["cnn"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(c.moving_proba(X), before["moving"], rtol=0, atol=1e-6)
    preds = c.predict_many(X)
    assert [p.label for p in preds] == before["labels"].tolist()
    assert [p.operational_state or "" for p in preds] == before["state"].tolist()
    np.testing.assert_allclose([p.confidence for p in preds], before["confidence"], rtol=0, atol=1e-6)
    assert len(set(before["labels"].tolist())) >= 5  # the returns exercise most classes, `unknown` included


def _rewritten(src: Path, dest: Path, drop: str, add: dict[str, bytes], weights: list[float] | None = None) -> Path:
    """A copy of bundle `src` without file `drop`, with files `add`, its card re-signed."""
    shutil.copytree(src, dest)
    card = read_card(dest)[0]
    (dest / drop).unlink()
    for name, data in add.items():
        (dest / name).write_bytes(data)
    card["files"] = sorted(set(card["files"]) - {drop} | set(add))
    if weights is not None:
        card["ensemble"]["weights"] = weights
    write_card(dest, card)
    return dest


def test_a_bundle_with_an_onnx_svm_is_refused_naming_the_rebuild(tiny_bundle: Path, tmp_path: Path) -> None:
    old = _rewritten(tiny_bundle, tmp_path / "old", "svm.npz", {"svm.onnx": b"an SVM exported as ONNX"})
    with pytest.raises(SignaturesError, match=r"svm\.onnx is a model format this version does not read; "
                                              r"rebuild the bundle with `authn models train`") as info:
        Classifier(old)
    assert info.value.exit_code == 2 and "\n" not in str(info.value)


def test_a_bundle_missing_a_member_its_vote_weighs_is_refused(tiny_bundle: Path, tmp_path: Path) -> None:
    bad = _rewritten(tiny_bundle, tmp_path / "bad", "svm.npz", {}, weights=[1.0, 1.0, 1.0])
    with pytest.raises(SignaturesError, match="weighs svm and the bundle does not ship it"):
        Classifier(bad)
    ok = _rewritten(tiny_bundle, tmp_path / "ok", "svm.npz", {}, weights=[0.0, 1.0, 0.0])  # a site bundle's layout
    c = Classifier(ok)
    assert c.ensemble_proba(np.zeros(c.n_features)).shape == (1, len(c.classes))
    with pytest.raises(SignaturesError, match="ships no svm model"):
        c.member_proba("svm", np.zeros(c.n_features))
