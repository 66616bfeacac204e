"""Run time against error: pipeline configurations on one held-out simulated set, Pareto front.

Every configuration sees the same returns (scenes drawn with seeds and continuous
geometry never used in training). Time per return = feature extraction + the
classifier(s) of that configuration, medians measured here; error = 1 - macro F1 per
SNR, and the false-alarm rate (`bird`/`none` called a UAV). The shipped bundle serves
the first group; configurations that change the features (a shorter dwell, the quick
feature tier) get a Random Forest retrained here on the bundle's training spec (its
first `n_train` returns, same seed), next to a reference RF retrained the same way on
the full features.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from lab.bench.variants import (features_half, features_quarter, features_quarter_quick, features_quick,
                                  features_third)
from signatures.features import FEATURE_NAMES, QUICK_FEATURES, extract
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.sampling import SceneDistribution, sample_scene
from signatures.sim.simulate import simulate

#: (name, feature mode, classifier) ; feature modes: gated at the known range, CFAR-detected, full cube
CONFIGS = (
    ("gated + ensemble (default)", "gated", "ensemble"),
    ("gated + RF", "gated", "rf"),
    ("gated + SVM", "gated", "svm"),
    ("gated + kNN", "gated", "knn"),
    ("gated + CNN", "gated", "cnn"),
    ("gated + cascade (CNN always)", "gated", "cascade-always"),
    ("CFAR-detected + ensemble", "detect", "ensemble"),
    ("full cube + ensemble", "full", "ensemble"),
)


#: (name, featurizer, feature names the RF sees, featurizer of the training set). The quick tier
#: computes its subset exactly as the full extraction does, so it trains on the full set's columns.
RETRAINED = (
    ("gated + RF retrained (reference)", extract, FEATURE_NAMES, extract),
    ("gated, quick tier (paper's 11 + gate physics) + RF", features_quick, QUICK_FEATURES, extract),
    ("gated, first 1/2 of the dwell + RF", features_half, FEATURE_NAMES, features_half),
    ("gated, first 1/3 of the dwell + RF", features_third, FEATURE_NAMES, features_third),
    ("gated, first 1/4 of the dwell + RF", features_quarter, FEATURE_NAMES, features_quarter),
    ("gated, first 1/4 of the dwell, quick tier + RF", features_quarter_quick, QUICK_FEATURES,
     features_quarter_quick),
)


@dataclass
class Point:
    name: str
    ms_per_return: float
    f1_by_snr: dict[float, float]
    far: float
    pareto: bool = False

    def mean_error(self, snrs: tuple[float, ...]) -> float:
        """1 - macro F1, averaged over `snrs` (the error axis of the front and the plot)."""
        return 1.0 - float(np.mean([self.f1_by_snr[s] for s in snrs]))


#: The held-out scenes (SNR fixed per group): 60 m to 1.1 km, 40 % hovering (birds too), clutter
#: in 40 %; birds with the `BirdParams` default flap amplitude; an empty scene is clutter only.
HELD_OUT_SCENES = SceneDistribution(order=("range", "speed", "elevation", "snr", "clutter"), range_m=(60.0, 1100.0),
                                    elevation_deg=(0.0, 40.0), hover_fraction=0.4, speed_mps=(1.0, 15.0),
                                    clutter_band=(0.6, 1.0), clutter_db=(0.0, 10.0), bird_wing_m=(0.15, 0.5),
                                    bird_flap_hz=(3.0, 10.0), none_clutter_db=(0.0, 15.0))


def _scenes(preset: str, snrs: tuple[float, ...], per_class: int, seed: int):
    rng = np.random.default_rng([seed, 9001])
    profiles = shipped_profiles()
    for snr in snrs:
        dist = replace(HELD_OUT_SCENES, snr_db=snr)
        for label in [*profiles, "bird", "none"]:
            for _ in range(per_class):
                scene = sample_scene(rng, profiles.get(label, label), dist)
                rec, truth = simulate(scene, get_preset(preset), int(rng.integers(2**31)) + 10**9)
                yield snr, label, rec, truth


def _classify(clf, mode: str) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    if mode == "ensemble":
        return lambda X, rd: clf.ensemble_proba(X)
    if mode == "cnn":
        return lambda X, rd: clf.cnn_proba(rd)
    if mode == "cascade-always":
        return lambda X, rd: 0.5 * (clf.ensemble_proba(X) + clf.cnn_proba(rd))
    return lambda X, rd: clf.member_proba(mode, X)


def extract_full_cube(rec, expected_range_m: float | None = None):
    """The ungated baseline: the range-Doppler map and the spectrogram of every range bin (what
    an implementation computes before looking at the target), then the features."""
    from signatures.dsp import rd
    from signatures.dsp import timefreq as tf
    from signatures.features import extract

    spectrum = rd.range_fft(rd.prepare(rec.iq).iq)
    rd.rd_map(spectrum, rec.config)
    tf.spectrogram(spectrum, rec.config, *tf.stft_params(rec.config, rec.n_chirps))
    return extract(rec)


#: Feature modes of the shipped-bundle configurations: (featurizer, uses the known range)
_MODES = {
    "gated": (extract, True),
    "detect": (extract, False),
    "full": (extract_full_cube, False),
}


def _interleaved(fns: dict[str, Callable[[int], object]], n: int) -> tuple[dict[str, list], dict[str, float]]:
    """Run every function on item i in turn, i = 0..n-1, starting with a different one each
    time: all configurations are timed under the same machine conditions (this machine is
    shared and drifts by tens of percent over minutes). Returns outputs and median ms."""
    keys = list(fns)
    out: dict[str, list] = {k: [] for k in keys}
    times: dict[str, list[float]] = {k: [] for k in keys}
    for i in range(n):
        for k in keys[i % len(keys):] + keys[:i % len(keys)]:
            t0 = time.perf_counter()
            out[k].append(fns[k](i))
            times[k].append((time.perf_counter() - t0) * 1e3)
    return out, {k: statistics.median(v) for k, v in times.items()}


def run(preset: str, snrs: tuple[float, ...] = (0.0, 10.0, 20.0), per_class: int = 20, seed: int = 5,
        progress: Callable[[int], None] | None = None, n_train: int = 3000) -> list[Point]:
    """The grid on one held-out set; `n_train` returns train each retrained RF (0: none).

    Feature extraction and classification are timed interleaved across configurations."""
    from signatures.train.evaluate import metrics
    from signatures.classify.inference import load_classifier

    clf = load_classifier(preset)
    data = list(_scenes(preset, snrs, per_class, seed))
    labels = np.array([label for _, label, _, _ in data])
    snr_of = np.array([snr for snr, _, _, _ in data])
    gates = [_gate_of(label, rec, truth) for _, label, rec, truth in data]
    retrained = _retrain(clf, preset, n_train) if n_train else []
    featurizers = {m: (fn, use_gate) for m, (fn, use_gate) in _MODES.items()}
    featurizers |= {name: (fn, True) for name, fn, _, _ in retrained}

    first = next(iter(featurizers))

    def featurize(key: str) -> Callable[[int], object]:
        fn, use_gate = featurizers[key]

        def one(i: int) -> object:
            if progress and key == first:  # one tick per return
                progress(1)
            return fn(data[i][2], gates[i] if use_gate else None)
        return one

    feats, ftime = _interleaved({k: featurize(k) for k in featurizers}, len(data))
    predictors: dict[str, tuple[Callable[[np.ndarray, np.ndarray], np.ndarray], np.ndarray, np.ndarray, list]] = {}
    for name, fmode, cmode in CONFIGS:
        if cmode in ("cnn", "cascade-always") and not clf.has_cnn:
            continue
        rows = feats[fmode]
        predictors[name] = (_classify(clf, cmode), np.stack([f.as_array() for f in rows]),
                            np.stack([f.rd_patch for f in rows]), rows)
    for name, _, cols, forest in retrained:
        rows = feats[name]
        predictors[name] = (lambda X, rd, forest=forest: forest.predict_proba(X),
                            np.stack([r.as_array() for r in rows])[:, cols], np.zeros((len(rows), 1)), rows)
    n_timed = min(len(data), 200)
    _, ctime = _interleaved({k: (lambda i, p=p: p[0](p[1][i:i + 1], p[2][i:i + 1])) for k, p in predictors.items()},
                            n_timed)
    mode_of = {name: fmode for name, fmode, _ in CONFIGS} | {name: name for name, _, _, _ in retrained}
    points = []
    for name, (predict, X, rd, rows) in predictors.items():
        p = predict(X, rd)
        detected = np.array([f.detected for f in rows])
        pred = np.where(detected, np.array(clf.classes)[np.argmax(p, axis=1)], "none")
        f1 = {float(s): metrics(labels[snr_of == s], pred[snr_of == s], p.max(axis=1)[snr_of == s],
                                clf.classes)["macro_f1"] for s in snrs}
        far = metrics(labels, pred, p.max(axis=1), clf.classes)["false_alarm_rate"]
        points.append(Point(name, ftime[mode_of[name]] + ctime[name], f1, far))
    _mark_front(points, snrs)
    return points


def _gate_of(label: str, rec, truth) -> float | None:
    lo, hi = rec.config.range_window_m
    return truth.range_m if label != "none" and lo <= truth.range_m < hi else None


def _retrain(clf, preset: str, n_train: int) -> list[tuple[str, Callable, list[int], object]]:
    """(name, featurizer, feature columns, forest) per RETRAINED configuration: an RF trained
    on the bundle's training spec (its first `n_train` returns, same seed)."""
    from signatures.train.classifiers import forest_arrays, make_rf
    from signatures.train.dataset import DatasetSpec, generate
    from signatures.classify.members import ForestArrays
    from signatures.profiles import UavProfile
    from signatures.train.training import GEOMETRY_FEATURES, LEVEL_FEATURES

    profiles = tuple(UavProfile.from_dict(p) for p in clf.card["profiles"])
    seed = int(clf.card["training"]["seed"])
    spec = DatasetSpec(split="train", n=n_train, preset=preset, profiles=profiles, seed=seed)
    index = {c: i for i, c in enumerate(clf.classes)}
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (name, featurize, names, train_featurize) in enumerate(RETRAINED):
            train = generate(spec, train_featurize, workers=2)
            cols = [FEATURE_NAMES.index(n) for n in names if n not in GEOMETRY_FEATURES + LEVEL_FEATURES]
            rf = make_rf(seed).fit(train.X[:, cols], np.array([index[c] for c in train.y]))
            path = Path(tmp) / f"rf{k}.npz"
            np.savez(path, **forest_arrays(rf, len(clf.classes)))
            out.append((name, featurize, cols, ForestArrays(path)))
    return out


def _mark_front(points: list[Point], snrs: tuple[float, ...]) -> None:
    """Pareto-optimal in (time, mean error over SNRs): nothing is both faster and at least as good."""
    err = {p.name: p.mean_error(snrs) for p in points}
    for p in points:
        p.pareto = not any(q is not p and q.ms_per_return <= p.ms_per_return and err[q.name] <= err[p.name]
                           and (q.ms_per_return < p.ms_per_return or err[q.name] < err[p.name]) for q in points)


def near_floor(points: list[Point], floor_ms: float, factor: float = 3.0, snr: float = 10.0,
               min_f1: float = 0.95) -> list[Point]:
    """Front points within `factor` x the FFT floor's time with macro F1 >= `min_f1` at `snr`
    (how close to the physical floor a configuration gets without losing accuracy)."""
    return [p for p in points if p.pareto and p.ms_per_return <= factor * floor_ms
            and p.f1_by_snr.get(snr, 0.0) >= min_f1]


def plot(points: list[Point], snrs: tuple[float, ...], path, floor_ms: float | None = None) -> None:
    """Error against time, one numbered marker per configuration (mean error over `snrs`, with
    the per-SNR errors as faint marks), the Pareto front as a line, the FFT floor and 3x it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, legend_ax) = plt.subplots(1, 2, figsize=(11, 4.8), gridspec_kw={"width_ratios": [3, 1.7]})
    mean_err = [p.mean_error(snrs) for p in points]
    for s, marker in zip(snrs, "o^sDv"):
        ax.scatter([p.ms_per_return for p in points], [1.0 - p.f1_by_snr[s] for p in points], marker=marker,
                   s=14, alpha=0.35, label=f"{s:g} dB")
    colours = ["tab:red" if p.pareto else "black" for p in points]
    ax.scatter([p.ms_per_return for p in points], mean_err, c=colours, s=36, zorder=3, label="mean")
    for k, (p, e) in enumerate(zip(points, mean_err), start=1):
        ax.annotate(str(k), (p.ms_per_return, e), textcoords="offset points", xytext=(4, 4), fontsize=8)
    front = sorted((p.ms_per_return, e) for p, e in zip(points, mean_err) if p.pareto)
    if front:
        ax.step(*zip(*front), where="post", color="tab:red", lw=1, alpha=0.7)
    if floor_ms:
        for x, text in ((floor_ms, "FFT floor"), (3 * floor_ms, "3x floor")):
            ax.axvline(x, color="grey", ls="--", lw=0.8)
            ax.text(x, ax.get_ylim()[1], " " + text, rotation=90, va="top", fontsize=7, color="grey")
    ax.set_xscale("log")
    from matplotlib.ticker import FuncFormatter, NullFormatter

    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))  # 0.2, 1, 10: not 2x10^-1
    ax.xaxis.set_minor_formatter(NullFormatter())  # minor labels collide on a short log axis
    ax.set_xlabel("time per return, ms (features + classifier, median)")
    ax.set_ylabel("error = 1 - macro F1")
    ax.set_title("run time against error (red = Pareto front on mean error)")
    ax.legend(title="SNR", fontsize=8)
    legend_ax.axis("off")
    lines = [f"{k:2d}  {p.name}{' *' if p.pareto else ''}" for k, p in enumerate(points, start=1)]
    legend_ax.text(0.0, 1.0, "\n".join(lines), va="top", fontsize=8, family="monospace")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
