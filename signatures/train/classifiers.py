"""The paper's classifiers as scikit-learn estimators (training side only).

kNN (k = 5, Euclidean), Random Forest and RBF SVM (one-vs-rest), each with its
scaling inside a Pipeline, and a soft-voting ensemble of the three whose averaged
probabilities are calibrated by temperature scaling (one parameter: it fixes the
over-/under-confidence of the average without changing its arg-max), fitted over a
bounded range: on a set the vote classifies perfectly the maximum-likelihood
temperature runs off to certainty, and no simulator earns that. Labels are integer
codes into the card's class list, so the exported arrays line up with it column for column.

Inference never imports this module: both sides vote and calibrate through `signatures.classify.ensemble`
(`MEMBERS`, `SoftVote`, `calibrate`), training with these pipelines as members, inference with the
numpy members (`signatures.classify.members`) built from the arrays exported here.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
from sklearn.ensemble import RandomForestClassifier
from sklearn.multiclass import OneVsRestClassifier
from sklearn.neighbors import KNeighborsClassifier
from sklearn.pipeline import Pipeline, make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from signatures.classify.ensemble import MEMBERS, SoftVote, calibrate, weighted_vote

__all__ = ["BETA_RANGE", "bounded_temperature", "fit_members", "fit_state_head", "forest_arrays", "knn_arrays",
           "make_knn", "make_member", "make_rf", "make_svm", "soft_vote", "svm_arrays", "vote_weights"]

#: Inverse temperatures a calibration may choose from: 0.25 (a quarter as sure) to 8 (p ** 8).
BETA_RANGE = (0.25, 8.0)


def make_knn() -> Pipeline:
    """The paper's kNN: k = 5, Euclidean distance (on standardised features)."""
    return make_pipeline(StandardScaler(), KNeighborsClassifier(n_neighbors=5, metric="euclidean"))


def make_rf(seed: int, n_estimators: int = 100) -> Pipeline:
    """Random Forest (no scaler: trees are scale-free); leaves of >= 2 samples keep the file small."""
    return make_pipeline(RandomForestClassifier(
        n_estimators=n_estimators, min_samples_leaf=2, random_state=seed, n_jobs=1))


def make_svm(seed: int) -> Pipeline:
    """RBF SVM, one-vs-rest as in the paper, Platt probabilities per binary machine."""
    return make_pipeline(StandardScaler(), OneVsRestClassifier(
        SVC(kernel="rbf", C=10.0, gamma="scale", probability=True, random_state=seed)))


def make_member(name: str, seed: int) -> Pipeline:
    if name == "knn":
        return make_knn()
    if name == "rf":
        return make_rf(seed)
    if name == "svm":
        return make_svm(seed)
    raise ValueError(f"unknown model {name!r}")


def _fit(model: Pipeline, X: np.ndarray, y: np.ndarray) -> Pipeline:
    """Fit; scikit-learn 1.9 deprecates SVC(probability=True) (removed in 1.11, hence the pin
    in pyproject): the shipped SVM arrays carry libsvm's Platt parameters (`svm_arrays`)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=FutureWarning, message=".*probab.*")
        return model.fit(X, y)


def fit_members(X: np.ndarray, y: np.ndarray, seed: int) -> dict[str, Pipeline]:
    """Fit kNN, RF and SVM on the same data."""
    return {name: _fit(make_member(name, seed), X, y) for name in MEMBERS}


def vote_weights(probs: Sequence[np.ndarray], y_val: np.ndarray) -> list[float]:
    """Integer member weights (0-3 each) with the best validation accuracy, then log-loss, from
    each member's validation probabilities (in the members' order).

    Equal weights let the weakest member (kNN) drag the vote below the best one.
    """
    import itertools

    best: tuple[float, float] | None = None
    chosen = [1.0] * len(probs)
    for w in itertools.product(range(4), repeat=len(probs)):
        if not any(w):
            continue
        p = weighted_vote(probs, w)
        key = (-float(np.mean(p.argmax(1) == y_val)), -float(np.mean(np.log(p[np.arange(len(y_val)), y_val] + 1e-12))))
        if best is None or key < best:
            best, chosen = key, [float(x) for x in w]
    return chosen


def soft_vote(members: dict[str, Pipeline], X: np.ndarray, weights: list[float]) -> np.ndarray:
    """The members' weighted mean probabilities: the ensemble's vote before calibration (members of
    weight 0 are not run), by the `SoftVote` inference applies."""
    return SoftVote(list(members.values()), weights).predict_proba(X)


def bounded_temperature(proba: np.ndarray, y: np.ndarray) -> float:
    """The inverse temperature in `BETA_RANGE` minimising the log-loss of `calibrate(proba, beta)`
    on labels `y` (a bounded scalar search on log beta; a set the vote separates perfectly stops at
    the upper bound instead of running off to certainty)."""
    from scipy.optimize import minimize_scalar

    rows = np.arange(len(y))

    def loss(log_beta: float) -> float:
        return -float(np.mean(np.log(calibrate(proba, float(np.exp(log_beta)))[rows, y] + 1e-12)))

    lo, hi = np.log(BETA_RANGE[0]), np.log(BETA_RANGE[1])
    res = minimize_scalar(loss, bounds=(lo, hi), method="bounded", options={"xatol": 1e-6})
    best = min((float(res.x), lo, hi), key=loss)  # the bounds themselves, where the optimum lies beyond
    return float(np.exp(best))


def knn_arrays(model: Pipeline, X_train: np.ndarray, y_train: np.ndarray, n_classes: int) -> dict[str, np.ndarray]:
    """A fitted kNN pipeline as plain arrays (`knn.npz`): scaler, standardised training set, labels, k.

    `X_train`, `y_train`: what the pipeline was fitted on. The reference set is the pipeline's own
    scaler applied to it (exactly what the neighbour search stores at fit time), through public API.
    An ONNX kNN graph cost ~14 ms per return; the same vote in numpy costs tens of
    microseconds (`signatures.classify.members.KnnArrays`), with no pickle and no scikit-learn.
    """
    scaler, knn = model.steps[0][1], model.steps[-1][1]
    if len(X_train) != knn.n_samples_fit_ or len(y_train) != len(X_train):
        raise ValueError(f"the kNN was fitted on {knn.n_samples_fit_} returns, "
                         f"got {len(X_train)} returns and {len(y_train)} labels")
    return {"mean": scaler.mean_.astype(np.float64), "scale": scaler.scale_.astype(np.float64),
            "refs": np.ascontiguousarray(scaler.transform(X_train), dtype=np.float32),
            "labels": np.asarray(y_train).astype(np.int64), "k": np.array(knn.n_neighbors),
            "n_classes": np.array(n_classes)}


def forest_arrays(model: Pipeline | RandomForestClassifier, n_classes: int) -> dict[str, np.ndarray]:
    """A fitted Random Forest as plain arrays (`rf.npz`): every tree's nodes in one table.

    Evaluated in numpy (`signatures.classify.members.ForestArrays`): a cold check then never
    imports onnxruntime (~25 ms) nor opens its sessions (~9 ms each). Leaf values are
    class fractions in `n_classes` columns (classes the forest never saw stay 0).
    """
    forest = model.steps[-1][1] if hasattr(model, "steps") else model
    feature, threshold, left, right, value, roots = [], [], [], [], [], []
    offset = 0
    for est in forest.estimators_:
        t = est.tree_
        leaf = t.children_left < 0
        roots.append(offset)
        feature.append(np.where(leaf, 0, t.feature))
        threshold.append(np.where(leaf, 0.0, t.threshold))
        left.append(np.where(leaf, np.arange(t.node_count), t.children_left) + offset)
        right.append(np.where(leaf, np.arange(t.node_count), t.children_right) + offset)
        v = t.value[:, 0, :]
        frac = np.zeros((t.node_count, n_classes))
        frac[:, forest.classes_.astype(np.int64)] = v / np.maximum(v.sum(axis=1, keepdims=True), 1e-300)
        value.append(frac)
        offset += t.node_count
    return {"feature": np.concatenate(feature).astype(np.int32),
            "threshold": np.concatenate(threshold).astype(np.float64),
            "left": np.concatenate(left).astype(np.int32), "right": np.concatenate(right).astype(np.int32),
            "value": np.concatenate(value).astype(np.float32), "roots": np.array(roots, dtype=np.int32),
            "depth": np.array(max(e.tree_.max_depth for e in forest.estimators_))}


def svm_arrays(model: Pipeline, n_classes: int) -> dict[str, np.ndarray]:
    """A fitted one-vs-rest RBF SVM pipeline as plain arrays (`svm.npz`): the scaler, and per binary
    machine its support vectors, dual coefficients, intercept and Platt parameters (A, B).

    Evaluated in numpy (`signatures.classify.members.SvmArrays`, libsvm's own probability steps), so that
    a check whose ensemble weighs the SVM never imports onnxruntime (~100 ms of a cold start).
    """
    scaler, ovr = model.steps[0][1], model.steps[-1][1]
    machines = list(ovr.estimators_)
    if len(machines) < 2 or not all(isinstance(m, SVC) and m.kernel == "rbf" and m.probability for m in machines):
        raise ValueError("svm_arrays needs a one-vs-rest of at least two RBF SVCs with probabilities")
    starts = np.cumsum([0] + [len(m.support_vectors_) for m in machines])
    return {"mean": scaler.mean_.astype(np.float64), "scale": scaler.scale_.astype(np.float64),
            "support": np.concatenate([m.support_vectors_ for m in machines]).astype(np.float64),
            "starts": starts.astype(np.int64), "dual": np.concatenate([m.dual_coef_[0] for m in machines]),
            "intercept": np.array([m.intercept_[0] for m in machines]),
            **_platt(machines),
            "gamma": np.array([m._gamma for m in machines]), "classes": ovr.classes_.astype(np.int64),
            "n_classes": np.array(n_classes)}


def _platt(machines: list) -> dict[str, np.ndarray]:
    """The machines' Platt parameters (A, B) (deprecated attributes in scikit-learn 1.9: see `_fit`)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=FutureWarning, message=".*prob[AB]_.*")
        return {"prob_a": np.array([m.probA_[0] for m in machines]),
                "prob_b": np.array([m.probB_[0] for m in machines])}


def fit_state_head(X: np.ndarray, moving: np.ndarray, seed: int) -> Pipeline:
    """Second head: hovering (0) / moving (1), a 50-tree RF on UAV returns only (shipped as
    `rf_state.npz`, evaluated in numpy: a forest alone keeps onnxruntime off every check)."""
    return _fit(make_rf(seed, n_estimators=50), X, moving.astype(np.int64))
