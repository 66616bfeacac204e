"""One bundle for a band of carriers, measured: the same scenes rendered at several
carriers of one waveform, their features before and after `signatures.classify.carrier.normalise`, and
a bundle trained at the middle carrier classifying all of them.

    python -m lab.bench.carrier_band --model DIR --carriers 3.30e9,3.35e9,3.40e9 --n 300 --snr 20,29

`--model`: a bundle (e.g. `authn models train --radar-config` of `cw-sband` at 3.35 GHz); its
waveform, with each carrier in turn, renders the test-block scenes (`signatures.train.dataset`, seed
1000: never a training scene) with the same simulator seed, so a scene differs between carriers
only by the carrier. Reported per feature: the median |change| between the outer carriers and
the middle one, raw and normalised, over the feature's spread (std) across scenes (detected
returns: what a check classifies); per carrier
and SNR: the bundle's ensemble and system accuracy (cascade + open set) with and without
normalisation. Nothing here is tuned.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace

import numpy as np


def render(model_dir: str, carriers: tuple[float, ...], n: int, snr: float, seed: int = 1000):
    """(X per carrier: (len(carriers), n, features), labels): the test scenes at each carrier."""
    from signatures.train.dataset import DatasetSpec, draw_scene
    from signatures.features import extract
    from signatures.classify.inference import load_classifier
    from signatures.profiles import shipped_profiles
    from signatures.sim.simulate import simulate

    clf = load_classifier(path=model_dir)
    wf = clf.waveform
    presets = [replace(wf, name=f"{wf.name}@{f:g}", config=wf.config.replace(carrier_hz=f))
               for f in carriers]
    spec = DatasetSpec(preset=wf, profiles=tuple(shipped_profiles().values()), split="test", n=n, seed=seed,
                       snr_db=float(snr))
    X = np.zeros((len(carriers), n, clf.n_features), dtype=np.float32)
    labels = []
    for i in range(n):
        scene, sim_seed = draw_scene(spec, i)
        labels.append(scene.label)
        for j, pre in enumerate(presets):
            rec, _ = simulate(scene, pre, seed=sim_seed)
            X[j, i] = extract(rec).as_array()
    return clf, X, np.array(labels)


def drift(clf, X: np.ndarray, carriers: tuple[float, ...], mid: int) -> dict[str, dict[str, float]]:
    """Per feature, over the returns detected at the middle carrier (a check classifies only
    those): spread across scenes, and the largest over the other carriers of the median |change|
    from the middle carrier, raw and normalised, each over that spread."""
    out = {}
    names = list(clf.feature_names)
    if "detected" in names:
        X = X[:, X[mid][:, names.index("detected")] > 0.5]
    norm = [clf.on_carrier(X[j], carriers[j]) for j in range(len(carriers))]
    for k, name in enumerate(names):
        spread = float(np.std(X[mid][:, k]))
        if spread == 0:
            continue
        raw = max(float(np.median(np.abs(X[j][:, k] - X[mid][:, k]))) for j in range(len(carriers)) if j != mid)
        nrm = max(float(np.median(np.abs(norm[j][:, k] - X[mid][:, k]))) for j in range(len(carriers)) if j != mid)
        out[name] = {"spread": spread, "raw": raw / spread, "normalised": nrm / spread}
    return out


def accuracy(clf, X: np.ndarray, labels: np.ndarray, carrier_hz: float | None) -> dict[str, float]:
    """Ensemble (closed-set) and system (what `authn check` uses) accuracy."""
    Xn = clf.on_carrier(X, carrier_hz)
    ens = np.array(clf.classes)[np.argmax(clf.ensemble_proba(Xn), axis=1)]
    system = np.array([p.label for p in clf.predict_many(Xn)])
    return {"ensemble": float(np.mean(ens == labels)), "system": float(np.mean(system == labels))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True)
    ap.add_argument("--carriers", default="3.30e9,3.35e9,3.40e9")
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--snr", default="20,29")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    carriers = tuple(float(c) for c in a.carriers.split(","))
    mid = len(carriers) // 2
    report: dict = {"carriers": carriers, "n": a.n, "per_snr": {}}
    for snr in (float(s) for s in a.snr.split(",")):
        t0 = time.perf_counter()
        clf, X, labels = render(a.model, carriers, a.n, snr)
        row = {"drift": drift(clf, X, carriers, mid), "accuracy": {}}
        for j, f in enumerate(carriers):
            row["accuracy"][f"{f:g}"] = {"raw": accuracy(clf, X[j], labels, None),
                                         "normalised": accuracy(clf, X[j], labels, f)}
        report["per_snr"][f"{snr:g}"] = row
        print(f"SNR {snr:g} dB ({time.perf_counter() - t0:.0f} s, {a.n} scenes, bundle at "
              f"{clf.waveform.config.carrier_hz / 1e9:g} GHz)")
        print("  carrier   ensemble raw / normalised   system raw / normalised")
        for f, acc in row["accuracy"].items():
            r, n_ = acc["raw"], acc["normalised"]
            print(f"  {float(f) / 1e9:<8g}  {r['ensemble']:.3f} / {n_['ensemble']:.3f}"
                  f"              {r['system']:.3f} / {n_['system']:.3f}")
        print("  feature drift, median |change| over scene spread (raw -> normalised), largest first:")
        for name, d in sorted(row["drift"].items(), key=lambda kv: -max(kv[1]["raw"], kv[1]["normalised"]))[:12]:
            print(f"    {name:26s} {d['raw']:.3f} -> {d['normalised']:.3f}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(report, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
