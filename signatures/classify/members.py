"""The ensemble's members as numpy estimators with scikit-learn's `predict_proba` contract.

Training fits scikit-learn estimators (`signatures.train.classifiers`) and exports each as plain arrays
(`.npz`, loaded without pickle); each class here is built from those arrays and answers what the
fitted estimator answers: `classes_` (the integer class codes, the card's class order) and
`predict_proba(X) -> (n, len(classes_))`, equal to scikit-learn's within float rounding
(`tests/classifiers/test_one_contract.py` compares them member by member). The soft vote and the
temperature that combine them are `signatures.classify.ensemble`; the CNN, an ONNX graph, is `OnnxCnn`.
No scikit-learn here: a check imports numpy only (onnxruntime only when the cascade runs the CNN).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from signatures.classify.ensemble import calibrate
from signatures.errors import SignaturesError

__all__ = ["ForestArrays", "KnnArrays", "OnnxCnn", "SvmArrays", "k_smallest", "load_member"]


def _arrays(path: Path, **kinds: Any) -> dict[str, Any]:
    """The named members of an .npz (no pickle), each as its numpy dtype, or `int` for a scalar."""
    with np.load(path, allow_pickle=False) as z:
        return {k: int(z[k]) if kind is int else z[k].astype(kind) for k, kind in kinds.items()}


class KnnArrays:
    """k-nearest-neighbour vote from `knn.npz`: the fitted `make_pipeline(StandardScaler(), KNeighborsClassifier)`'s
    `predict_proba`."""

    def __init__(self, path: Path) -> None:
        a = _arrays(path, mean=np.float64, scale=np.float64, refs=np.float64, labels=np.int64, k=int, n_classes=int)
        self.mean, self.scale, self.refs, self.labels = a["mean"], a["scale"], a["refs"], a["labels"]
        self.k, self.n_classes = a["k"], a["n_classes"]
        self.classes_ = np.arange(self.n_classes)
        self._ref_sq = np.sum(self.refs * self.refs, axis=1)
        self._refs_m2 = -2.0 * self.refs  # exact: d2 below is the same floats as |r|^2 - 2 z.r

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        Z = (np.asarray(X, dtype=np.float64) - self.mean) / self.scale
        d2 = Z @ self._refs_m2.T
        d2 += self._ref_sq  # + |z|^2: the same for every reference
        k = min(self.k, len(self.refs))
        nn = k_smallest(d2, k)
        out = np.zeros((len(Z), self.n_classes))
        np.add.at(out, (np.repeat(np.arange(len(Z)), k), self.labels[nn].ravel()), 1.0 / k)
        return out.astype(np.float32)


def k_smallest(d: np.ndarray, k: int) -> np.ndarray:
    """Column indices of each row's k smallest values in `d` (rows, n), nearest first, ties by
    index. A full selection (argpartition) over thousands of references costs ~4x this: every
    block's minimum bounds the row's k-th smallest from above, so only the blocks whose minimum
    is at or under the k-th smallest block minimum (a few more than k) are searched."""
    n_rows, n = d.shape
    block = max(16, math.isqrt(n))
    n_blocks = n // block
    if n_blocks < 2 * k:  # too few blocks to bound anything
        return _k_smallest_full(d, k)
    blocks = d[:, :n_blocks * block].reshape(n_rows, n_blocks, block)
    mins = np.fmin.reduce(blocks, axis=2)  # NaN-blind: a block's NaN must not hide its smallest value
    bound = np.partition(mins, k - 1, axis=1)[:, k - 1]
    rb, bb = np.nonzero(mins <= bound[:, None])
    r, j = np.nonzero(blocks[rb, bb] <= bound[rb, None])
    r, c = rb[r], bb[r] * block + j
    tr, tc = np.nonzero(d[:, n_blocks * block:] <= bound[:, None])  # the last, partial block
    r, c = np.concatenate([r, tr]), np.concatenate([c, tc + n_blocks * block])
    if np.any(np.bincount(r, minlength=n_rows) < k):  # NaN distances: no bound holds
        return _k_smallest_full(d, k)
    order = np.lexsort((c, d[r, c], r))  # by row, then value, then index
    r, c = r[order], c[order]
    return c[np.searchsorted(r, np.arange(n_rows))[:, None] + np.arange(k)]


def _k_smallest_full(d: np.ndarray, k: int) -> np.ndarray:
    """`k_smallest` by a full selection over every column."""
    return np.argpartition(d, k - 1, axis=1)[:, :k]


class ForestArrays:
    """Random Forest vote from `rf.npz`: the fitted RandomForestClassifier's `predict_proba`.

    All trees advance one level per step for all rows at once; leaves point to themselves,
    so `depth` steps land every row on its leaf in every tree.
    """

    def __init__(self, path: Path) -> None:
        a = _arrays(path, feature=np.intp, threshold=np.float64, left=np.intp, right=np.intp, value=np.float32,
                    roots=np.intp, depth=int)
        self.feature, self.threshold, self.left, self.right = a["feature"], a["threshold"], a["left"], a["right"]
        self.value, self.roots, self.depth = a["value"], a["roots"], a["depth"]
        n = len(self.feature)
        if not (len(self.threshold) == len(self.left) == len(self.right) == len(self.value) == n) or n == 0 \
                or min(self.left.min(), self.right.min(), self.roots.min()) < 0 \
                or max(self.left.max(), self.right.max(), self.roots.max()) >= n:
            raise SignaturesError(f"{path}: inconsistent tree arrays")
        #: node i's children side by side, (right, left): the next node is child[2 i + go_left],
        #: one gather where np.where over both children took three
        self._child = np.stack([self.right, self.left], axis=1).ravel()
        self.classes_ = np.arange(self.value.shape[1])

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        # scikit-learn compares float32 features with float64 thresholds
        Z = np.ascontiguousarray(np.asarray(X, dtype=np.float32), dtype=np.float64)
        if self.feature.max() >= Z.shape[1]:
            raise SignaturesError(f"forest uses feature {self.feature.max()}, the vector has {Z.shape[1]}")
        flat, row = Z.ravel(), (np.arange(len(Z)) * Z.shape[1])[:, None]  # Z[r, f] is flat[row[r] + f]
        node = np.broadcast_to(self.roots, (len(Z), len(self.roots)))
        for _ in range(self.depth):
            go_left = flat[row + self.feature[node]] <= self.threshold[node]
            node = self._child[2 * node + go_left]
        return self.value[node].mean(axis=1)


class SvmArrays:
    """One-vs-rest RBF SVM from `svm.npz` (what OneVsRestClassifier(SVC(probability=True)).predict_proba
    computes: each machine's decision value, libsvm's Platt sigmoid and two-class coupling, the
    machines' positive probabilities normalised to sum to 1)."""

    #: libsvm's bounds on a pairwise probability and its coupling's tolerance (eps 0.005 / k, k = 2)
    MIN_PROB, EPS, MAX_ITER = 1e-7, 0.0025, 100

    def __init__(self, path: Path) -> None:
        a = _arrays(path, mean=np.float64, scale=np.float64, support=np.float64, starts=np.int64, dual=np.float64,
                    intercept=np.float64, prob_a=np.float64, prob_b=np.float64, gamma=np.float64,
                    classes=np.int64, n_classes=int)
        self.mean, self.scale, self.support, self.starts = a["mean"], a["scale"], a["support"], a["starts"]
        self.dual, self.intercept, self.a, self.b = a["dual"], a["intercept"], a["prob_a"], a["prob_b"]
        self.gamma, self.classes, self.n_classes = a["gamma"], a["classes"], a["n_classes"]
        m = len(self.intercept)
        if not (len(self.starts) == m + 1 and self.starts[0] == 0 and self.starts[-1] == len(self.support)
                == len(self.dual) and np.all(np.diff(self.starts) > 0) and len(self.classes) == m
                and len(self.a) == len(self.b) == len(self.gamma) == m and m >= 2
                and self.classes.min() >= 0 and self.classes.max() < self.n_classes):
            raise SignaturesError(f"{path}: inconsistent SVM arrays")
        self._sv_sq = np.sum(self.support * self.support, axis=1)
        self._neg_gamma = -np.repeat(self.gamma, np.diff(self.starts))  # per support vector
        self.classes_ = np.arange(self.n_classes)

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        # the scaler as scikit-learn applies it to float32 rows (in their dtype)
        Z = ((np.asarray(X, dtype=np.float32) - self.mean).astype(np.float32) / self.scale).astype(np.float32)
        Z = Z.astype(np.float64)
        d2 = np.maximum(np.sum(Z * Z, axis=1)[:, None] + self._sv_sq[None, :] - 2.0 * Z @ self.support.T, 0.0)
        # every machine at once: its support vectors' kernel terms summed per machine
        dec = np.add.reduceat(np.exp(d2 * self._neg_gamma) * self.dual, self.starts[:-1], axis=1) + self.intercept
        pos = self._coupled((-dec * self.a + self.b).ravel()).reshape(dec.shape)
        out = np.zeros((len(Z), self.n_classes))
        out[:, self.classes] = pos / np.maximum(pos.sum(axis=1, keepdims=True), 1e-300)
        return out.astype(np.float32)

    @classmethod
    def _coupled(cls, f_apb: np.ndarray) -> np.ndarray:
        """P(positive class) of one machine from A f + B (f libsvm's decision value): libsvm's sigmoid,
        clipped, then its pairwise coupling (`multiclass_probability`) iterated as libsvm does for k = 2."""
        e = np.exp(-np.abs(f_apb))
        r = np.clip(np.where(f_apb >= 0, e / (1.0 + e), 1.0 / (1.0 + e)), cls.MIN_PROB, 1.0 - cls.MIN_PROB)
        r01, r10 = r, 1.0 - r  # r01: P(negative class, libsvm's first) over the pair
        q = np.array([[r10 * r10, -r10 * r01], [-r10 * r01, r01 * r01]])  # (2, 2, rows)
        p = np.full((2, len(r)), 0.5)
        for _ in range(cls.MAX_ITER):
            qp = np.einsum("tjn,jn->tn", q, p)
            pqp = np.sum(p * qp, axis=0)
            live = np.max(np.abs(qp - pqp), axis=0) >= cls.EPS
            if not live.any():
                break
            for t in range(2):
                diff = np.where(live, (-qp[t] + pqp) / q[t, t], 0.0)
                p[t] += diff
                pqp = (pqp + diff * (diff * q[t, t] + 2 * qp[t])) / (1 + diff) / (1 + diff)
                qp = (qp + diff * q[t]) / (1 + diff)
                p = p / (1 + diff)
        return p[1]


class OnnxCnn:
    """The cascade's CNN (`cnn.onnx`, exported by torch): `predict_proba(rd)` is the softmax of its logits
    over RD patches (n, H, W) standardised by the card's mean and std. onnxruntime opens on first use."""

    def __init__(self, path: Path, mean: float, std: float, n_classes: int) -> None:
        import onnxruntime as ort

        opts = ort.SessionOptions()
        opts.intra_op_num_threads = 1
        opts.inter_op_num_threads = 1
        opts.log_severity_level = 3
        self._session = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
        self.mean, self.std = mean, std
        self.classes_ = np.arange(n_classes)

    def predict_proba(self, rd: np.ndarray) -> np.ndarray:
        x = (np.asarray(rd, dtype=np.float32) - self.mean) / self.std
        x = x.reshape(-1, 1, *x.shape[-2:])
        logits = self._session.run(["logits"], {"rd": x})[0].astype(np.float64)
        return calibrate(np.exp(logits - logits.max(axis=1, keepdims=True)), 1.0)


#: The array member of each file stem ("rf" and "rf_state" are forests).
_KINDS: dict[str, type[KnnArrays] | type[ForestArrays] | type[SvmArrays]] = {
    "knn": KnnArrays, "rf": ForestArrays, "rf_state": ForestArrays, "svm": SvmArrays}


def load_member(path: Path) -> KnnArrays | ForestArrays | SvmArrays:
    """The numpy member saved at `path` (`knn.npz`, `rf.npz`, `rf_state.npz`, `svm.npz`)."""
    return _KINDS[path.stem](path)
