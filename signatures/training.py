"""Train a model bundle for one preset: simulate, fit, calibrate, export ONNX, write the card.

Everything is seeded, so the same command rebuilds the same bundle (byte-identical
ONNX files and card on the same library versions). Validation data (its own grid
blocks and seeds) calibrates the ensemble, sets the open-set thresholds and the
cascade threshold; test data is left to `signatures.evaluate`.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from signatures.dataset import GENERATOR_VERSION, Dataset, DatasetSpec, Featurizer, generate
from signatures.modelcard import library_versions, write_card
from signatures.profiles import UavProfile
from signatures.radar import get_preset

#: Open-set threshold: this quantile of known validation returns' manifold distance.
OPENSET_QUANTILE = 0.995
#: Where the target is, not what it is: left out of the type classifiers (kept for the state heads).
GEOMETRY_FEATURES = ("mean_range_m", "range_m", "mean_doppler_mps", "radial_velocity_mps")
#: Absolute level (radar calibration x range): would make decisions depend on IQ scaling.
LEVEL_FEATURES = ("peak_amplitude_db",)
CASCADE_GRID = (0.0, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99)


@dataclass(frozen=True)
class TrainConfig:
    preset: str
    profiles: tuple[UavProfile, ...]
    n_train: int = 3000
    n_val: int = 1000
    seed: int = 0
    cnn: bool = False
    openset_quantile: float = OPENSET_QUANTILE
    workers: int = 2


def _codes(ds: Dataset) -> np.ndarray:
    index = {c: i for i, c in enumerate(ds.classes)}
    return np.array([index[str(v)] for v in ds.y], dtype=np.int64)


def _acc_f1(y: np.ndarray, pred: np.ndarray, n: int) -> dict[str, float]:
    f1 = []
    for c in range(n):
        tp = np.sum((pred == c) & (y == c))
        fp = np.sum((pred == c) & (y != c))
        fn = np.sum((pred != c) & (y == c))
        f1.append(2 * tp / max(2 * tp + fp + fn, 1))
    return {"accuracy": round(float(np.mean(pred == y)), 6), "macro_f1": round(float(np.mean(f1)), 6)}


def choose_cascade_threshold(p_ens: np.ndarray, p_cnn: np.ndarray, y: np.ndarray) -> float:
    """Smallest threshold of CASCADE_GRID with the best validation accuracy (0 = never run the CNN)."""
    best, best_t = -1.0, 0.0
    for t in CASCADE_GRID:
        used = p_ens.max(axis=1) < t
        p = p_ens.copy()
        p[used] = 0.5 * (p[used] + p_cnn[used])
        acc = float(np.mean(p.argmax(axis=1) == y))
        if acc > best + 1e-9:
            best, best_t = acc, t
    return best_t


def train_bundle(cfg: TrainConfig, out: Path, featurizer: Featurizer | None = None,
                 cache: Path | None | bool = None, progress: bool = False) -> dict[str, Any]:
    """Build the bundle of `cfg` in folder `out` (replaced); returns its card."""
    from signatures import classifiers as clf
    from signatures.cnn import export_cnn, torch_available, train_cnn
    from signatures.inference import Classifier
    from signatures.onnx_export import check_export, sklearn_to_onnx
    from signatures.openset import fit_openset

    common = dict(preset=cfg.preset, profiles=cfg.profiles, seed=cfg.seed)
    train = generate(DatasetSpec(split="train", n=cfg.n_train, **common), featurizer,
                     workers=cfg.workers, cache=cache, progress=progress)
    val = generate(DatasetSpec(split="val", n=cfg.n_val, **common), featurizer,
                   workers=cfg.workers, cache=cache, progress=progress)
    y, yv = _codes(train), _codes(val)
    n_cls, n_all = len(train.classes), train.X.shape[1]
    cols = [i for i, n in enumerate(train.feature_names) if n not in GEOMETRY_FEATURES + LEVEL_FEATURES]
    Xt, Xv, n_feat = train.X[:, cols], val.X[:, cols], len(cols)
    members = clf.fit_members(Xt, y, cfg.seed)
    weights = clf.vote_weights(members, Xv, yv)
    ensemble = clf.calibrated_ensemble(members, Xv, yv, weights)
    uav = np.isin(train.y, [p.slug for p in cfg.profiles])
    heads = clf.fit_state_heads(train.X[uav], train.moving[uav], cfg.seed)

    tmp = Path(tempfile.mkdtemp(prefix=f".{cfg.preset}-", dir=out.parent if out.parent.exists() else None))
    try:
        files = []
        for name, model in members.items():
            sklearn_to_onnx(model, n_feat, tmp / f"{name}.onnx")
            files.append(f"{name}.onnx")
        export_err = {n: round(check_export(m, tmp / f"{n}.onnx", Xv), 6) for n, m in members.items()}
        for name, model in heads.items():
            sklearn_to_onnx(model, n_all, tmp / f"{name}_state.onnx")
            files.append(f"{name}_state.onnx")
        pred_val = ensemble.predict(Xv)
        openset = fit_openset(Xt, y, n_cls, Xv, yv, pred_val, cfg.openset_quantile)
        np.savez(tmp / "openset.npz", **openset.arrays())
        files.append("openset.npz")
        cnn_card = None
        if cfg.cnn and torch_available():
            net, mean, std = train_cnn(train.rd, y, n_cls, cfg.seed, progress=progress)
            export_cnn(net, train.rd.shape[1:], tmp / "cnn.onnx")
            files.append("cnn.onnx")
            cnn_card = {"input": "rd_patch", "shape": list(train.rd.shape[1:]), "input_mean": mean,
                        "input_std": std, "epochs": 12}
        card: dict[str, Any] = {
            "preset": cfg.preset,
            "radar": {**get_preset(cfg.preset).config.model_dump(exclude={"range_offset_m"}),
                      "n_chirps": get_preset(cfg.preset).n_chirps, "n_samples": get_preset(cfg.preset).n_samples},
            "classes": list(train.classes),
            "feature_names": list(train.feature_names),
            "class_features": [train.feature_names[i] for i in cols],
            "profiles": [p.model_dump(mode="json") for p in cfg.profiles],
            "training": {"seed": cfg.seed, "n_train": cfg.n_train, "n_val": cfg.n_val,
                         "generator_version": GENERATOR_VERSION,
                         "dataset": {k: v for k, v in DatasetSpec(split="train", n=1, **common).__dict__.items()
                                     if k in ("snr_db", "max_elevation_deg", "clutter_fraction", "clutter_db")},
                         "command": _command(cfg)},
            "models": {"knn": "StandardScaler + KNeighborsClassifier(k=5, euclidean)",
                       "rf": "RandomForestClassifier(100 trees, min_samples_leaf=2)",
                       "svm": "StandardScaler + OneVsRest(SVC(rbf, C=10, gamma=scale, Platt))",
                       "state_heads": "same three on hovering/moving, UAV returns only"},
            "ensemble": {"members": list(members), "voting": "soft, weights chosen on validation data",
                         "weights": weights,
                         "temperature_beta": round(clf.temperature_beta(ensemble), 9)},
            "open_set": {"method": "mean distance to 5 nearest training returns of the predicted class, "
                                   "standardised features", "quantile": cfg.openset_quantile},
            "cnn": cnn_card,
            "cascade": {"threshold": 0.0, "combine": "mean of ensemble and CNN probabilities"},
            "onnx_export_max_abs_error": export_err,
            "libraries": library_versions(),
            "files": files,
        }
        write_card(tmp, card)
        model = Classifier(tmp)
        p_ens = model.ensemble_proba(val.X)
        metrics = {m: _acc_f1(yv, model.member_proba(m, val.X).argmax(axis=1), n_cls) for m in clf.MEMBERS}
        metrics["ensemble"] = _acc_f1(yv, p_ens.argmax(axis=1), n_cls)
        if model.has_cnn:
            p_cnn = model.cnn_proba(val.rd)
            card["cascade"]["threshold"] = choose_cascade_threshold(p_ens, p_cnn, yv)
            metrics["cnn"] = _acc_f1(yv, p_cnn.argmax(axis=1), n_cls)
            used = p_ens.max(axis=1) < card["cascade"]["threshold"]
            p = p_ens.copy()
            p[used] = 0.5 * (p[used] + p_cnn[used])
            metrics["cascade"] = {**_acc_f1(yv, p.argmax(axis=1), n_cls),
                                  "cnn_run_fraction": round(float(used.mean()), 6)}
        unk = model.unknown_mask(val.X, p_ens.argmax(axis=1))
        metrics["open_set_false_rejection_val"] = round(float(unk.mean()), 6)
        card["metrics"] = {"validation": metrics}
        card["files"] = files
        write_card(tmp, card)
        if out.exists():
            shutil.rmtree(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(tmp), str(out))
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return card


def _command(cfg: TrainConfig) -> str:
    parts = ["authn models train", f"--preset {cfg.preset}", f"--samples {cfg.n_train}",
             f"--val-samples {cfg.n_val}", f"--seed {cfg.seed}"]
    return " ".join(parts + (["--cnn"] if cfg.cnn else []))
