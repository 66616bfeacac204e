"""The paper's metrics (accuracy, macro F1, TPC, FAR, delay; docs/classifiers.md) for a model bundle on fresh test data.

Test data comes from the `test` grid blocks with its own seed, one dataset per SNR,
so nothing here was seen in training or validation. Every model is run through the
shipped ONNX bundle (what `authn check` runs), not through scikit-learn.

Metrics per model and per SNR: accuracy, macro F1, true-positive confidence (mean
probability of correct predictions), false alarm rate (`bird`/`none` returns
declared a UAV, `unknown` included), classification time delay (median feature
extraction + median single-return model time), per-class precision / recall / F1
and the confusion matrix. The `system` row is the ensemble (+ cascade) with
open-set rejection: what the decision layer receives.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from signatures.train.dataset import Dataset, DatasetSpec, Featurizer, generate
from signatures.classify.inference import MEMBERS, Classifier
from signatures.profiles import NON_UAV_CLASSES, UNKNOWN, UavProfile

__all__ = ["DEFAULT_SNRS", "PAPER_FIGURES", "evaluate", "latency_ms", "metrics", "plot", "predictions",
           "test_summary", "write_json"]

DEFAULT_SNRS = (-20.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 20.0, 30.0)
PAPER_FIGURES = {"knn": 0.71, "rf": 1.00, "svm": 0.88}  # accuracy, paper section V


def metrics(y: Sequence[str], pred: Sequence[str], conf: np.ndarray, classes: Sequence[str]) -> dict[str, Any]:
    """Accuracy, macro F1 (over the true classes), TPC, FAR, per-class scores, confusion matrix."""
    y, pred = np.asarray(y, dtype=str), np.asarray(pred, dtype=str)
    cols = list(classes) + ([UNKNOWN] if UNKNOWN in pred and UNKNOWN not in classes else [])
    rows = [c for c in cols if c in set(y)] + sorted(set(y) - set(cols))
    cm = [[int(np.sum((y == r) & (pred == c))) for c in cols] for r in rows]
    per_class = {}
    for c in rows:
        tp = int(np.sum((y == c) & (pred == c)))
        fp, fn = int(np.sum((y != c) & (pred == c))), int(np.sum((y == c) & (pred != c)))
        prec, rec = tp / max(tp + fp, 1), tp / max(tp + fn, 1)
        per_class[c] = {"precision": round(prec, 4), "recall": round(rec, 4),
                        "f1": round(2 * tp / max(2 * tp + fp + fn, 1), 4), "support": int(np.sum(y == c))}
    ok = y == pred
    non_uav = np.isin(y, NON_UAV_CLASSES)
    alarms = non_uav & ~np.isin(pred, NON_UAV_CLASSES)
    return {
        "n": int(len(y)),
        "accuracy": round(float(ok.mean()), 4),
        "macro_f1": round(float(np.mean([v["f1"] for v in per_class.values()])), 4),
        "tp_confidence": round(float(conf[ok].mean()) if ok.any() else 0.0, 4),
        "false_alarm_rate": round(float(alarms.sum() / max(non_uav.sum(), 1)), 5),
        "per_class": per_class,
        "confusion": {"rows": rows, "cols": cols, "matrix": cm},
    }


def _timed(fn, n: int = 200) -> float:
    """Median wall time (ms) of fn(i) over n single returns."""
    t = []
    for i in range(n):
        t0 = time.perf_counter()
        fn(i)
        t.append(time.perf_counter() - t0)
    return float(np.median(t) * 1e3)


def latency_ms(model: Classifier, X: np.ndarray, rd: np.ndarray, n: int = 200) -> dict[str, float]:
    """Median single-return inference time per model (features excluded)."""
    n = min(n, len(X))
    out = {m: _timed(lambda i, m=m: model.member_proba(m, X[i:i + 1]), n) for m in MEMBERS}
    out["ensemble"] = _timed(lambda i: model.ensemble_proba(X[i:i + 1]), n)
    if model.has_cnn:
        out["cnn"] = _timed(lambda i: model.cnn_proba(rd[i:i + 1]), n)
    out["system"] = _timed(lambda i: model.predict(X[i], rd[i]), n)
    return {k: round(v, 4) for k, v in out.items()}


def predictions(model: Classifier, ds: Dataset) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Labels and confidences of every model on a dataset (vectorised)."""
    cls = np.array(model.classes)
    out = {}
    for m in MEMBERS:
        p = model.member_proba(m, ds.X)
        out[m] = (cls[p.argmax(1)], p.max(1))
    p_ens = model.ensemble_proba(ds.X)
    out["ensemble"] = (cls[p_ens.argmax(1)], p_ens.max(1))
    if model.has_cnn:
        p = model.cnn_proba(ds.rd)
        out["cnn"] = (cls[p.argmax(1)], p.max(1))
    p_cas, _ = model.cascade_proba(ds.X, ds.rd)
    if model.has_cnn:
        out["cascade"] = (cls[p_cas.argmax(1)], p_cas.max(1))
    k = p_cas.argmax(1)
    sys_lab = np.where(model.unknown_mask(ds.X, k), UNKNOWN, cls[k])
    out["system"] = (sys_lab, p_cas.max(1))
    return out


def evaluate(model: Classifier, snrs: Sequence[float], n_per_snr: int, seed: int,
             unknown_profiles: Sequence[UavProfile] = (), featurizer: Featurizer | None = None,
             cache: Path | None | bool = None, progress: bool = False, workers: int = 2) -> dict[str, Any]:
    """Metrics per model and SNR on test-split data, open-set rates on never-trained profiles."""
    known = tuple(UavProfile.from_dict(p) for p in model.card["profiles"])
    report: dict[str, Any] = {"preset": model.preset, "card_sha256": model.card_digest, "seed": seed,
                              "n_per_snr": n_per_snr, "per_snr": {}, "open_set": {}}
    first: Dataset | None = None
    for snr in snrs:
        ds = generate(DatasetSpec(preset=model.waveform, profiles=known, split="test", n=n_per_snr, seed=seed,
                                  snr_db=float(snr)), featurizer, cache=cache, progress=progress, workers=workers)
        first = first or ds
        row = {}
        predictions_cache = predictions(model, ds)
        for name, (lab, conf) in predictions_cache.items():
            row[name] = metrics(ds.y, lab, conf, model.classes)
        known_uav = ~np.isin(ds.y, NON_UAV_CLASSES)
        row["system"]["known_uav_called_unknown"] = round(float(np.mean(
            np.asarray(predictions_cache["system"][0])[known_uav] == UNKNOWN)), 4) if known_uav.any() else 0.0
        report["per_snr"][f"{snr:g}"] = row
        if unknown_profiles:
            uk = generate(DatasetSpec(preset=model.waveform, profiles=tuple(unknown_profiles), split="test",
                                      n=max(n_per_snr // 2, 10), seed=seed, snr_db=float(snr), include_non_uav=False),
                          featurizer, cache=cache, progress=progress, workers=workers)
            lab, _ = predictions(model, uk)["system"]
            report["open_set"][f"{snr:g}"] = {
                "unknown_rate": round(float(np.mean(lab == UNKNOWN)), 4),
                "per_profile": {p.slug: round(float(np.mean(lab[uk.y == p.slug] == UNKNOWN)), 4)
                                for p in unknown_profiles},
                "called": {c: int(np.sum(lab == c)) for c in sorted(set(lab.tolist()))}}
    assert first is not None
    lat = latency_ms(model, first.X, first.rd)
    feat = float(np.median(first.feature_ms))
    report["latency_ms"] = lat
    report["feature_ms_median"] = round(feat, 3)
    report["classification_time_delay_ms"] = {k: round(feat + v, 3) for k, v in lat.items()}
    return report


def test_summary(report: dict[str, Any]) -> dict[str, Any]:
    """Per SNR, what `authn check` would do with these returns (the `system` model: ensemble,
    cascade, open set): accuracy and macro F1; of the known-airframe returns, the share labelled
    with their own airframe (`genuine_confirmed`: a genuine claim's radar evidence agrees), with
    another enrolled airframe (`wrong_airframe`: the evidence an impostor needs) and `unknown`;
    bird / none returns called an airframe (`false_alarm_rate`); never-trained profiles called
    `unknown` (`unknown_rejection`, when the report has them)."""
    out: dict[str, Any] = {"seed": report["seed"], "n_per_snr": report["n_per_snr"], "per_snr": {}}
    for snr, row in report["per_snr"].items():
        m = row["system"]
        cm = m["confusion"]
        uav = [c for c in cm["cols"] if c not in NON_UAV_CLASSES and c != UNKNOWN]
        n = confirmed = wrong = 0
        for r, counts in zip(cm["rows"], cm["matrix"]):
            if r not in uav:
                continue
            called = dict(zip(cm["cols"], counts))
            n += sum(counts)
            confirmed += called.get(r, 0)
            wrong += sum(v for c, v in called.items() if c in uav and c != r)
        doc = {"accuracy": m["accuracy"], "macro_f1": m["macro_f1"],
               "genuine_confirmed": round(confirmed / max(n, 1), 4), "wrong_airframe": round(wrong / max(n, 1), 4),
               "called_unknown": m["known_uav_called_unknown"], "false_alarm_rate": m["false_alarm_rate"]}
        if snr in report["open_set"]:
            doc["unknown_rejection"] = report["open_set"][snr]["unknown_rate"]
        out["per_snr"][snr] = doc
    return out


def write_json(report: dict[str, Any], path: Path) -> None:
    path.write_text(json.dumps(report, indent=1, sort_keys=True) + "\n")


def plot(report: dict[str, Any], folder: Path) -> list[Path]:
    """Confusion matrices (per model, highest SNR) and accuracy-versus-SNR curves as PNGs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    snrs = sorted(report["per_snr"], key=float)
    models = list(report["per_snr"][snrs[0]])
    written = []
    fig, ax = plt.subplots(figsize=(6, 4))
    for m in models:
        ax.plot([float(s) for s in snrs], [report["per_snr"][s][m]["accuracy"] for s in snrs], marker="o", label=m)
    ax.set_xlabel("SNR per IF sample (dB)")
    ax.set_ylabel("accuracy")
    ax.set_title(f"accuracy vs SNR ({report['preset']} preset)")
    ax.grid(alpha=0.3)
    ax.legend()
    path = folder / f"accuracy_vs_snr_{report['preset']}.png"
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    written.append(path)
    for s in (snrs[-1], "0") if "0" in snrs and snrs[-1] != "0" else (snrs[-1],):
        for m in models:
            cm = report["per_snr"][s][m]["confusion"]
            mat = np.array(cm["matrix"])
            fig, ax = plt.subplots(figsize=(5, 4))
            ax.imshow(mat, cmap="Blues")
            ax.set_xticks(range(len(cm["cols"])), cm["cols"], rotation=45)
            ax.set_yticks(range(len(cm["rows"])), cm["rows"])
            dark = mat.max() / 2 if mat.size else 0  # white text on the dark half of the colour map
            for (i, j), v in np.ndenumerate(mat):
                ax.text(j, i, str(v), ha="center", va="center", fontsize=8, color="white" if v > dark else "black")
            ax.set_xlabel("predicted")
            ax.set_ylabel("true")
            ax.set_title(f"{m}, {report['preset']}, SNR {s} dB")
            path = folder / f"confusion_{report['preset']}_{m}_snr{s}.png"
            fig.savefig(path, dpi=110, bbox_inches="tight")
            plt.close(fig)
            written.append(path)
    return written
