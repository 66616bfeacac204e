"""The soft vote and its temperature: one implementation for training and inference.

Both take estimators with scikit-learn's contract (`classes_`, `predict_proba(X) -> (n, classes)`):
training passes the fitted scikit-learn pipelines (`signatures.train.classifiers`), inference the numpy
members built from a bundle's arrays (`signatures.classify.members`), so the probabilities a bundle's weights
and temperature were chosen on are computed by the code that applies them. `SoftVote` is what
`VotingClassifier(voting="soft", weights=...)` computes on prefitted members, without running a
member of weight 0; `Temperature` is the map of `CalibratedClassifierCV(method="temperature")`,
softmax(beta log p), with the inverse temperature fitted over a bounded range instead
(`signatures.train.classifiers.bounded_temperature`), so a bundle ships one number, not a calibrator object.
Numpy only: a check imports no scikit-learn.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

__all__ = ["MEMBERS", "ProbabilisticClassifier", "SoftVote", "Temperature", "calibrate", "weighted_vote"]

#: The ensemble's members, in the order of the card's `ensemble.weights` (training and inference).
MEMBERS = ("knn", "rf", "svm")


class ProbabilisticClassifier(Protocol):
    """scikit-learn's classifier contract as the ensemble reads it."""

    classes_: np.ndarray

    def predict_proba(self, X: Any) -> np.ndarray: ...


def calibrate(avg_proba: np.ndarray, beta: float) -> np.ndarray:
    """Temperature scaling, softmax(beta * log p): what scikit-learn's
    `CalibratedClassifierCV(method="temperature")` computes on the averaged vote. The 1e-12 keeps a
    class no member voted for finite (it stays the least likely)."""
    z = beta * np.log(avg_proba + 1e-12)
    z -= z.max(axis=1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)


def weighted_vote(probs: Sequence[Any], weights: Sequence[float]) -> np.ndarray:
    """The weighted mean of members' probabilities (members of weight 0 left out: their entry may be
    anything), in the members' dtype."""
    return sum(w * p for w, p in zip(weights, probs) if w) / float(sum(weights))


class SoftVote:
    """The weighted mean of the members' `predict_proba` (`VotingClassifier(voting="soft")` on
    prefitted members). A member of weight 0 is never run and may be None (a bundle need not ship it)."""

    def __init__(self, members: Sequence[ProbabilisticClassifier | None], weights: Sequence[float]) -> None:
        if len(members) != len(weights) or not any(weights):
            raise ValueError("a soft vote needs one weight per member, not all 0")
        self._voting = [(m, float(w)) for m, w in zip(members, weights) if w and m is not None]
        if len(self._voting) != sum(1 for w in weights if w):
            raise ValueError("a member with a weight is missing")
        self.classes_ = np.asarray(self._voting[0][0].classes_)

    def predict_proba(self, X: Any) -> np.ndarray:
        return weighted_vote([m.predict_proba(X) for m, _ in self._voting], [w for _, w in self._voting])


class Temperature:
    """An estimator's probabilities calibrated by one inverse temperature `beta` (`calibrate`)."""

    def __init__(self, estimator: ProbabilisticClassifier, beta: float) -> None:
        self.estimator, self.beta = estimator, float(beta)
        self.classes_ = np.asarray(estimator.classes_)

    def predict_proba(self, X: Any) -> np.ndarray:
        return calibrate(np.asarray(self.estimator.predict_proba(X), dtype=np.float64), self.beta)
