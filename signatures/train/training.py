"""Train a model bundle for one waveform: simulate, fit, calibrate, export the arrays, write the card.

Everything is seeded, so the same command rebuilds the same bundle (byte-identical
files and card on the same library versions). Validation data (its own grid
blocks and seeds) weighs the ensemble's members, sets the open-set thresholds and the
cascade threshold; the same blocks rendered with domain randomisation calibrate its
temperature. With `n_test`, held-out test blocks (`signatures.train.evaluate`) measure the
finished bundle and the card keeps the summary (`metrics.test`).
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from signatures.train.dataset import GENERATOR_VERSION, Dataset, DatasetSpec, Featurizer, generate
from signatures.sim.sampling import NuisanceDistribution
from signatures.classify.modelcard import library_versions, write_card
from signatures.profiles import UavProfile
from signatures.radar import C, Preset, get_preset

if TYPE_CHECKING:
    from signatures.classify.openset import PhysicsCheck

__all__ = ["CALIBRATION_NUISANCE", "CASCADE_GRID", "GEOMETRY_FEATURES", "LEVEL_FEATURES", "OPENSET_MODE",
           "OPENSET_QUANTILE", "PHYSICS_METHOD", "PHYS_MAX_REL_TOL", "PHYS_MIN_FLASH_SCORE", "PHYS_Z",
           "TEST_SEED_OFFSET", "TrainConfig", "choose_cascade_threshold", "default_samples", "train_bundle"]

#: Open-set threshold: this quantile of known validation returns' manifold distance.
OPENSET_QUANTILE = 0.995
#: Open-set test shipped by default: the physical-consistency check alone. On validation data
#: (README "Open set") the distance test adds false rejections of known classes and no rejections
#: of never-trained airframes.
OPENSET_MODE = "physics"
#: Physical check: tolerance = Z sigmas of (estimator std (+) rotor-rate jitter); the rate test
#: abstains when that tolerance exceeds MAX_REL_TOL of the profile's flash rate (half of the 20 %
#: separation the check must resolve). Fixed a priori, not tuned on the invented profiles.
PHYS_Z = 4.0
PHYS_MAX_REL_TOL = 0.10
PHYS_MIN_FLASH_SCORE = 1.0
#: The physical check in one line, for the card.
PHYSICS_METHOD = ("|flash_rate - F_profile| <= max(z*sqrt(std^2 + (jitter*F)^2), min_rel_tol*F), or within that "
                  "of an aliased_rate_slips multiple of F when the tips alias; abstains if that tolerance > "
                  "max_rel_tol*F, no rate or flash_score < min; unaliased tips: tip_speed <= "
                  "T_profile*(1+3*jitter) + max(z*tip_std + 1 Doppler bin, min_rel_tip_tol*T); "
                  "UAV predictions only")
#: What the ensemble's temperature is fitted on: validation scenes with the simulator's nuisances
#: drawn at random (`signatures.sim.sampling`). A plain simulator's validation set is classified almost
#: perfectly, so the log-loss fit there only learns to be sure (an inverse temperature of 163 for
#: `wide`), which no other world bears out.
CALIBRATION_NUISANCE = NuisanceDistribution()
#: Where the target is, not what it is: left out of the type classifiers (kept for the state heads).
GEOMETRY_FEATURES = ("mean_range_m", "range_m", "mean_doppler_mps", "radial_velocity_mps")
#: Absolute level (radar calibration x range): would make decisions depend on IQ scaling.
LEVEL_FEATURES = ("peak_amplitude_db",)
CASCADE_GRID = (0.0, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99)
#: Seed of the held-out test data: training seed + this (`authn models evaluate` defaults to 1000 too).
TEST_SEED_OFFSET = 1000


def default_samples(waveform: Preset) -> int:
    """Training returns for a cube size: 8000 up to 100k samples per cube (paper: 48k), 4000 up to
    1M (wide: 524k), else 2000; simulation time grows with the cube."""
    cells = waveform.n_chirps * waveform.n_samples
    return 8000 if cells <= 100_000 else 4000 if cells <= 1_000_000 else 2000


@dataclass(frozen=True)
class TrainConfig:
    """What a bundle is trained on. `preset`: the waveform, or a shipped preset's name."""

    preset: Preset | str
    profiles: tuple[UavProfile, ...]
    n_train: int = 3000
    n_val: int = 1000
    seed: int = 0
    cnn: bool = False
    openset_quantile: float = OPENSET_QUANTILE
    openset_mode: str = OPENSET_MODE
    workers: int = 2
    #: Profiles never trained on, for the card's validation open-set numbers (empty: none).
    unknown_profiles: tuple[UavProfile, ...] = ()
    n_unknown_val: int = 0
    #: Held-out test returns per SNR of `test_snrs` measured into the card (0: none)
    n_test: int = 0
    test_snrs: tuple[float, ...] = (0.0, 10.0, 20.0)
    #: domain randomisation of the training and validation scenes (None: the plain simulator)
    nuisance: NuisanceDistribution | None = None

    def __post_init__(self) -> None:
        if isinstance(self.preset, str):
            object.__setattr__(self, "preset", get_preset(self.preset))

    @property
    def waveform(self) -> Preset:
        assert isinstance(self.preset, Preset)  # resolved in __post_init__
        return self.preset


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
    from signatures.classify.inference import Classifier

    data = _Data.generate(cfg, featurizer, cache, progress)
    fit = _fit(cfg, data)
    tmp = Path(tempfile.mkdtemp(prefix=f".{cfg.waveform.name}-",
                                dir=out.parent if out.parent.exists() else None))
    try:
        files, export_err, all_tests = _write_arrays(cfg, data, fit, tmp)
        cnn_card = _train_cnn(cfg, data, fit, tmp, progress)
        if cnn_card is not None:
            files.append("cnn.onnx")
        card = _card(cfg, data, fit, files, export_err, cnn_card)
        write_card(tmp, card)
        model = Classifier(tmp)
        card["metrics"] = {"validation": _validation_metrics(cfg, data, fit, model, card, all_tests, featurizer,
                                                             cache, progress)}
        if cfg.n_test:
            from signatures.train.evaluate import evaluate, test_summary

            report = evaluate(model, cfg.test_snrs, cfg.n_test, cfg.seed + TEST_SEED_OFFSET,
                              cfg.unknown_profiles, featurizer, cache=cache, progress=progress, workers=cfg.workers)
            card["metrics"]["test"] = test_summary(report)
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


@dataclass(frozen=True)
class _Data:
    """The simulated returns of a training run: training, validation, and the domain-randomised
    validation returns the temperature is fitted on; `common`: the dataset spec they share."""

    train: Dataset
    val: Dataset
    cal: Dataset
    common: dict[str, Any]

    @classmethod
    def generate(cls, cfg: TrainConfig, featurizer: Featurizer | None, cache: Path | None | bool,
                 progress: bool) -> _Data:
        common = dict(preset=cfg.preset, profiles=cfg.profiles, seed=cfg.seed, nuisance=cfg.nuisance)
        train = generate(DatasetSpec(split="train", n=cfg.n_train, **common), featurizer,
                         workers=cfg.workers, cache=cache, progress=progress)
        val = generate(DatasetSpec(split="val", n=cfg.n_val, **common), featurizer,
                       workers=cfg.workers, cache=cache, progress=progress)
        # the temperature is fitted on returns with the nuisances no one simulator pins down (the
        # validation returns themselves when training is randomised already)
        cal_spec = {**common, "nuisance": cfg.nuisance or CALIBRATION_NUISANCE}
        cal = generate(DatasetSpec(split="val", n=cfg.n_val, **cal_spec), featurizer, workers=cfg.workers,
                       cache=cache, progress=progress)
        return cls(train, val, cal, common)


@dataclass(frozen=True)
class _Fit:
    """What training fitted: the ensemble's members on the class features `cols` (their
    validation probabilities, vote weights and temperature), the state head and the physical check."""

    cols: list[int]
    n_cls: int
    members: dict[str, Any]
    val_probs: list[np.ndarray]
    weights: list[float]
    beta: float
    state_head: Any
    phys: PhysicsCheck
    jitter: float
    tip_bin: float


def _fit(cfg: TrainConfig, data: _Data) -> _Fit:
    """Fit the ensemble's members, weigh them on validation data, calibrate the temperature, fit
    the state head and set up the physical check of this waveform."""
    from signatures.train import classifiers as clf
    from signatures.classify.openset import physics_check
    from signatures.sim.scene import Scene

    train, val, cal = data.train, data.val, data.cal
    cols = [i for i, n in enumerate(train.feature_names) if n not in GEOMETRY_FEATURES + LEVEL_FEATURES]
    members = clf.fit_members(train.X[:, cols], _codes(train), cfg.seed)
    val_probs = [m.predict_proba(val.X[:, cols]) for m in members.values()]  # once: weights, SVM export, open set
    weights = clf.vote_weights(val_probs, _codes(val))
    beta = clf.bounded_temperature(clf.soft_vote(members, cal.X[:, cols], weights), _codes(cal))
    uav = np.isin(train.y, [p.slug for p in cfg.profiles])
    state_head = clf.fit_state_head(train.X[uav], train.moving[uav], cfg.seed)
    wf = cfg.waveform
    jitter = float(Scene.model_fields["rotor_rate_jitter"].default)
    tip_bin = C / wf.config.carrier_hz / 2 / (wf.config.pri_s * wf.n_chirps)  # this waveform's Doppler bin
    phys = physics_check(train.classes, {p.slug: p for p in cfg.profiles}, train.feature_names, jitter,
                         tip_bin_mps=tip_bin, z=PHYS_Z, max_rel_tol=PHYS_MAX_REL_TOL,
                         min_flash_score=PHYS_MIN_FLASH_SCORE)
    return _Fit(cols, len(train.classes), members, val_probs, weights, beta, state_head, phys, jitter, tip_bin)


def _write_arrays(cfg: TrainConfig, data: _Data, fit: _Fit, tmp: Path) -> tuple[list[str], dict[str, float], Any]:
    """Write the members, the state head and the open set into `tmp`: (files, the SVM's export
    error, every open-set test through the shipped file's float32 round trip)."""
    from signatures.train import classifiers as clf
    from signatures.classify.ensemble import weighted_vote
    from signatures.classify.members import SvmArrays
    from signatures.classify.openset import MODES, OpenSet, fit_openset

    train, val = data.train, data.val
    y, n_cls, members = _codes(train), fit.n_cls, fit.members
    # every member as numpy arrays (signatures.classify.members reads them back)
    np.savez(tmp / "knn.npz", **clf.knn_arrays(members["knn"], train.X[:, fit.cols], y, n_cls))
    np.savez(tmp / "rf.npz", **clf.forest_arrays(members["rf"], n_cls))
    np.savez(tmp / "rf_state.npz", **clf.forest_arrays(fit.state_head, 2))
    np.savez(tmp / "svm.npz", **clf.svm_arrays(members["svm"], n_cls))
    files = ["knn.npz", "rf.npz", "rf_state.npz", "svm.npz"]
    svm_val = fit.val_probs[list(members).index("svm")]
    svm_err = np.max(np.abs(SvmArrays(tmp / "svm.npz").predict_proba(val.X[:, fit.cols]) - svm_val))
    export_err = {"svm": round(float(svm_err), 6)}
    pred_val = weighted_vote(fit.val_probs, fit.weights).argmax(axis=1)
    openset = fit_openset(train.X, y, n_cls, val.X, _codes(val), pred_val, cfg.openset_quantile,
                          class_cols=np.array(fit.cols, dtype=np.int64), physics=fit.phys, mode=cfg.openset_mode)
    np.savez(tmp / "openset.npz", **openset.arrays())  # only the shipped mode's tests
    files.append("openset.npz")
    # every test, through the same float32 round trip as the shipped file: the card's
    # validation numbers compare all modes
    return files, export_err, OpenSet.from_arrays(openset.arrays(MODES))


def _train_cnn(cfg: TrainConfig, data: _Data, fit: _Fit, tmp: Path, progress: bool) -> dict[str, Any] | None:
    """Train and export the CNN (`cnn.onnx`) where asked and torch is there: its card entry, else None."""
    from signatures.train.cnn import export_cnn, torch_available, train_cnn

    if not (cfg.cnn and torch_available()):
        return None
    rd = data.train.rd
    net, mean, std = train_cnn(rd, _codes(data.train), fit.n_cls, cfg.seed, progress=progress)
    export_cnn(net, rd.shape[1:], tmp / "cnn.onnx")
    return {"input": "rd_patch", "shape": list(rd.shape[1:]), "input_mean": mean, "input_std": std, "epochs": 12}


def _card(cfg: TrainConfig, data: _Data, fit: _Fit, files: list[str], export_err: dict[str, float],
          cnn_card: dict[str, Any] | None) -> dict[str, Any]:
    """The bundle's card before its metrics: waveform, features, training, models, ensemble, open set."""
    from signatures.train import classifiers as clf

    wf, train, cols = cfg.waveform, data.train, fit.cols
    dataset = {k: v for k, v in DatasetSpec(split="train", n=1, **data.common).__dict__.items()
               if k in ("snr_db", "max_elevation_deg", "clutter_fraction", "clutter_db")}
    card: dict[str, Any] = {
        "preset": wf.name,
        "radar": {**wf.config.to_dict(exclude=("range_offset_m",)),
                  "n_chirps": wf.n_chirps, "n_samples": wf.n_samples},
        "classes": list(train.classes),
        "feature_names": list(train.feature_names),
        "class_features": [train.feature_names[i] for i in cols],
        "profiles": [p.to_dict(json=True) for p in cfg.profiles],
        "training": {"seed": cfg.seed, "n_train": cfg.n_train, "n_val": cfg.n_val,
                     "generator_version": GENERATOR_VERSION,
                     "dataset": {**dataset, **({"randomisation": asdict(cfg.nuisance)} if cfg.nuisance else {})},
                     "command": _command(cfg)},
        "models": {"knn": "StandardScaler + KNeighborsClassifier(k=5, euclidean); shipped as knn.npz "
                          "(scaler, standardised training set, labels), evaluated in numpy",
                   "rf": "RandomForestClassifier(100 trees, min_samples_leaf=2)",
                   "svm": "StandardScaler + OneVsRest(SVC(rbf, C=10, gamma=scale, Platt))",
                   "state_head": "RandomForestClassifier(50 trees, min_samples_leaf=2) on hovering/moving, "
                                 "UAV returns only; shipped as rf_state.npz"},
        "ensemble": {"members": list(fit.members), "voting": "soft, weights chosen on validation data",
                     "weights": fit.weights, "temperature_beta": round(fit.beta, 9),
                     "calibration": f"log-loss on {cfg.n_val} domain-randomised validation returns, "
                                    f"inverse temperature bounded to {clf.BETA_RANGE[0]}..{clf.BETA_RANGE[1]}"},
        "open_set": {"mode": cfg.openset_mode,
                     "physics": {"method": PHYSICS_METHOD,
                                 "z": PHYS_Z, "max_rel_tol": PHYS_MAX_REL_TOL,
                                 "min_flash_score": PHYS_MIN_FLASH_SCORE, "rotor_rate_jitter": fit.jitter,
                                 "tip_bin_mps": round(fit.tip_bin, 6), **_physics_card(fit.phys)},
                     "distance": {"method": "mean distance to 5 nearest training returns of the predicted "
                                            "class, standardised type features",
                                  "quantile": cfg.openset_quantile}},
        "cnn": cnn_card,
        "cascade": {"threshold": 0.0, "combine": "mean of ensemble and CNN probabilities"},
        "export_max_abs_error": export_err,
        "libraries": library_versions(),
        "files": files,
    }
    if not wf.shipped:  # a shipped preset is named by `preset`; any other waveform is described here
        card["waveform"] = _waveform_card(wf, cfg.profiles)
    return card


def _validation_metrics(cfg: TrainConfig, data: _Data, fit: _Fit, model: Any, card: dict[str, Any], all_tests: Any,
                        featurizer: Featurizer | None, cache: Path | None | bool, progress: bool) -> dict[str, Any]:
    """The written bundle (`model`) measured on the validation returns: each member, the ensemble, the state
    head, the numpy forests against scikit-learn, the CNN cascade (its threshold set in `card`),
    and the open set."""
    from signatures.classify.ensemble import MEMBERS

    val, yv, n_cls = data.val, _codes(data.val), fit.n_cls
    p_ens = model.ensemble_proba(val.X)
    metrics = {m: _acc_f1(yv, model.member_proba(m, val.X).argmax(axis=1), n_cls) for m in MEMBERS}
    metrics["ensemble"] = _acc_f1(yv, p_ens.argmax(axis=1), n_cls)
    uav_v = np.isin(val.y, [p.slug for p in cfg.profiles])
    metrics["state_accuracy"] = round(float(np.mean((model.moving_proba(val.X[uav_v]) >= 0.5)
                                                    == val.moving[uav_v])), 6)
    metrics["forest_max_abs_error"] = round(max(  # numpy forests vs scikit-learn
        float(np.max(np.abs(fit.members["rf"].predict_proba(val.X[:, fit.cols]) - model.member_proba("rf", val.X)))),
        float(np.max(np.abs(fit.state_head.predict_proba(val.X[uav_v])[:, 1] - model.moving_proba(val.X[uav_v]))))),
        6)
    if model.has_cnn:
        p_cnn = model.cnn_proba(val.rd)
        card["cascade"]["threshold"] = choose_cascade_threshold(p_ens, p_cnn, yv)
        metrics["cnn"] = _acc_f1(yv, p_cnn.argmax(axis=1), n_cls)
        used = p_ens.max(axis=1) < card["cascade"]["threshold"]
        p = p_ens.copy()
        p[used] = 0.5 * (p[used] + p_cnn[used])
        metrics["cascade"] = {**_acc_f1(yv, p.argmax(axis=1), n_cls),
                              "cnn_run_fraction": round(float(used.mean()), 6)}
    uk = None
    if cfg.unknown_profiles and cfg.n_unknown_val:
        uk = generate(DatasetSpec(split="val", n=cfg.n_unknown_val, include_non_uav=False,
                                  **{**data.common, "profiles": cfg.unknown_profiles}),
                      featurizer, workers=cfg.workers, cache=cache, progress=progress)
    metrics["open_set"] = {"shipped_mode": cfg.openset_mode, **_open_set_metrics(model, all_tests, val, yv, p_ens,
                                                                                 uk, n_cls),
                           "unknown_profiles": [p.slug for p in cfg.unknown_profiles] if uk is not None else []}
    return metrics


def _open_set_metrics(model: Any, all_tests: Any, val: Dataset, yv: np.ndarray, p_ens: np.ndarray,
                      uk: Dataset | None, n_cls: int) -> dict[str, Any]:
    """Each open-set mode on the validation returns (known false rejection, the system's macro F1
    at SNR >= 10 dB) and, with `uk`, the returns of profiles never trained on (their rejection)."""
    pv = p_ens.argmax(axis=1)
    hi = val.snr_db >= 10
    pu = model.ensemble_proba(uk.X).argmax(axis=1) if uk is not None else None
    osv: dict[str, Any] = {}
    for mode in ("physics", "distance", "both"):
        unk = all_tests.unknown(model._x(val.X), pv, mode)
        sys_pred = np.where(unk, -1, pv)
        row = {"known_false_rejection": round(float(unk.mean()), 6),
               "known_false_rejection_snr_ge_10": round(float(unk[hi].mean()), 6) if hi.any() else None,
               "system_macro_f1_snr_ge_10": _acc_f1(yv[hi], sys_pred[hi], n_cls)["macro_f1"] if hi.any() else None}
        if uk is not None:
            uu = all_tests.unknown(model._x(uk.X), pu, mode)
            uhi = uk.snr_db >= 10
            row["unknown_rejection"] = round(float(uu.mean()), 6)
            row["unknown_rejection_snr_ge_10"] = round(float(uu[uhi].mean()), 6) if uhi.any() else None
        osv[mode] = row
    return osv


def _physics_card(phys: PhysicsCheck) -> dict[str, Any]:
    """The physical check's tolerance floors and aliasing slips for the card (the values
    `openset.npz` ships and inference applies)."""
    return {"min_rel_tol": phys.min_rel_tol, "min_rel_tip_tol": phys.min_rel_tip_tol,
            "aliased_rate_slips": list(phys.rate_slips)}


def _waveform_card(wf: Preset, profiles: tuple[UavProfile, ...]) -> dict[str, Any]:
    """A non-preset waveform in the card: what bundle lookup matches (`radar_config`, `key`) and
    which profiles' blade tips alias in it (the physical check then accepts flash-rate slips)."""
    return {"key": wf.key, "description": wf.describe(), "radar_config": wf.as_json(),
            "unambiguous_velocity_mps": round(wf.config.unambiguous_velocity_mps, 6),
            "tips_alias_when_hovering": [p.slug for p in profiles if wf.config.tip_aliases(p)]}


def _command(cfg: TrainConfig) -> str:
    wf = cfg.waveform
    source = f"--preset {wf.name}" if wf.shipped else "--radar-config RADAR.json (the card's waveform.radar_config)"
    parts = ["authn models train", source, f"--samples {cfg.n_train}", f"--val-samples {cfg.n_val}",
             f"--seed {cfg.seed}"]
    if cfg.n_test:
        parts.append(f"--test-samples {cfg.n_test}")
    return " ".join(parts + (["--cnn"] if cfg.cnn else []) + (["--randomise"] if cfg.nuisance else []))
