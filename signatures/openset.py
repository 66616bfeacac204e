"""Open-set rejection: a return far from every training return of its predicted class is `unknown`.

Method: distance to the class manifold. In the standardised feature space, the score
of a return is its mean Euclidean distance to the k nearest *training* returns of the
class the ensemble predicted. A class's threshold is the `quantile` of that score
over its own correctly classified *validation* returns, so by construction about
(1 - quantile) of known returns are falsely rejected, while an airframe whose
rotor rate or blade length the training set never saw lands off the manifold.
Why not a probability threshold: the ensemble is confidently wrong on unseen
airframes (an unknown quad sits on the far side of the decision boundary of
the nearest known one), so its maximum probability barely separates them (numbers
in README "Classifiers / Open set"). `bird` and `none` are classes, and are
checked the same way: a return that is neither a known UAV, a bird nor noise is
`unknown`.

numpy only: this runs on the inference path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def knn_distance(Z: np.ndarray, ref: np.ndarray, k: int) -> np.ndarray:
    """Mean distance of each row of Z to its k nearest rows of ref (excluding exact self-matches)."""
    d2 = (np.sum(Z * Z, axis=1)[:, None] - 2.0 * Z @ ref.T + np.sum(ref * ref, axis=1)[None, :])
    d = np.sqrt(np.maximum(d2, 0.0))
    kk = min(k, ref.shape[0])
    part = np.partition(d, kk - 1, axis=1)[:, :kk]
    return part.mean(axis=1)


@dataclass
class OpenSet:
    """Per-class reference sets (standardised) and rejection thresholds."""

    mean: np.ndarray
    scale: np.ndarray
    refs: list[np.ndarray]  # per class index
    thresholds: np.ndarray  # per class index; inf = never reject
    k: int = 5

    def standardise(self, X: np.ndarray) -> np.ndarray:
        return (np.asarray(X, dtype=np.float64) - self.mean) / self.scale

    def scores(self, X: np.ndarray, pred: np.ndarray) -> np.ndarray:
        """Distance of each return to the training manifold of its predicted class."""
        Z = self.standardise(X)
        out = np.empty(len(Z))
        for c in np.unique(pred):
            m = pred == c
            out[m] = knn_distance(Z[m], self.refs[int(c)], self.k)
        return out

    def unknown(self, X: np.ndarray, pred: np.ndarray) -> np.ndarray:
        """True where the return lies beyond its predicted class's threshold."""
        return self.scores(X, pred) > self.thresholds[np.asarray(pred, dtype=int)]

    def arrays(self) -> dict[str, np.ndarray]:
        """Flat arrays for an `.npz` (no pickle)."""
        out = {"mean": self.mean, "scale": self.scale, "thresholds": self.thresholds,
               "k": np.array(self.k)}
        out.update({f"ref_{i}": r.astype(np.float32) for i, r in enumerate(self.refs)})
        return out

    @classmethod
    def from_arrays(cls, z: dict[str, np.ndarray]) -> "OpenSet":
        n = len(z["thresholds"])
        return cls(mean=z["mean"], scale=z["scale"], thresholds=z["thresholds"], k=int(z["k"]),
                   refs=[z[f"ref_{i}"].astype(np.float64) for i in range(n)])


def fit_openset(X_train: np.ndarray, y_train: np.ndarray, n_classes: int, X_val: np.ndarray,
                y_val: np.ndarray, pred_val: np.ndarray, quantile: float, k: int = 5) -> OpenSet:
    """References from training data, thresholds from correctly classified validation returns."""
    mean = X_train.mean(axis=0).astype(np.float64)
    scale = X_train.std(axis=0).astype(np.float64)
    scale[scale == 0] = 1.0
    Z = (X_train - mean) / scale
    refs = [Z[y_train == c] for c in range(n_classes)]
    model = OpenSet(mean=mean, scale=scale, refs=refs, thresholds=np.full(n_classes, np.inf), k=k)
    s = model.scores(X_val, pred_val)
    ok = pred_val == y_val
    for c in range(n_classes):
        m = ok & (y_val == c)
        if m.sum() >= 5:
            model.thresholds[c] = float(np.quantile(s[m], quantile))
    return model
