"""Batch mode at fleet scale: per-return cost of batched features + classifier against the FFT
floor, the same accuracy as one return at a time, and registry-only rejections against the
I/O floor. All figures of one call come from one run on one machine (ratios, medians).
"""

from __future__ import annotations

import hashlib
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

#: Batch sizes of the per-return time curve.
SIZES = (1, 8, 64, 256, 1024)
SNRS = (0.0, 10.0, 20.0)


def _median_ms(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times)


def returns(preset: str, distinct: int = 64, seed: int = 5) -> tuple[list, list[float | None]]:
    """The bench's returns: `distinct` // 5 simulated scenes per class at 10 dB (the shipped
    UAVs, a bird, an empty scene), as (recordings, their gates' expected ranges)."""
    from lab.bench import pareto

    data = [(rec, pareto._gate_of(label, rec, truth))
            for _, label, rec, truth in pareto._scenes(preset, (10.0,), max(1, distinct // 5), seed)]
    return [r for r, _ in data], [g for _, g in data]


def curve(preset: str, sizes: tuple[int, ...] = SIZES, distinct: int = 64, seed: int = 5,
          budget_s: float = 20.0) -> dict[str, object]:
    """Per-return ms of batched features + classifier at each batch size, beside the single-return
    path and the FFT floor measured in the same run. Every size runs the same mix of returns:
    the `distinct` simulated returns in turn, in batches of that size, as many batches as cover
    them all at least once (a batch of 1: each return alone; 256: the returns repeated to fill
    it), so a small batch is not timed on the first few scenes only (`extract_many` splits a
    batch larger than memory allows). Measured
    **interleaved**: each round times the floor, one return at a time and every batch size once, in
    turn, so that a shared machine's drift hits them alike; rounds repeat until `budget_s` has
    passed (at least 3, at most 50), medians over rounds."""
    from lab.bench import perf
    from signatures.features import batch_size, extract_many
    from signatures.features import extract
    from signatures.classify.inference import load_classifier

    clf = load_classifier(preset)
    recs, gates = returns(preset, distinct, seed)

    def batched(b: int) -> tuple[Callable[[], object], int]:
        """Batches of b covering every return: (run them all, returns run)."""
        total = -(-max(b, len(recs)) // b) * b
        rows = [i % len(recs) for i in range(total)]
        batches = [([recs[i] for i in rows[s:s + b]], [gates[i] for i in rows[s:s + b]]) for s in range(0, total, b)]

        def run() -> object:
            return [clf.predict_many(np.stack([f.as_array() for f in extract_many(rs, gs)])) for rs, gs in batches]
        return run, total

    def single() -> object:
        return [clf.predict(f.as_array()) for f in (extract(r, g) for r, g in zip(recs, gates))]

    runs: dict[str, tuple[Callable[[], object], int]] = {"single": (single, len(recs))}
    runs.update({str(b): batched(b) for b in sizes})
    for fn, _ in runs.values():
        fn()  # warm: FFT workspaces, models, the allocator
    times: dict[str, list[float]] = {k: [] for k in runs}
    floors: list[float] = []
    t_end = time.perf_counter() + budget_s
    while len(floors) < 3 or (time.perf_counter() < t_end and len(floors) < 50):
        floors.append(perf.fft_floor(preset, repeats=5)["fft_ms"])
        for key, (fn, count) in runs.items():
            times[key].append(_median_ms(fn, 1) / count)
    out = {k: statistics.median(v) for k, v in times.items()}
    floor = statistics.median(floors)
    first = recs[0]
    return {"ms_per_return": out, "fft_floor_ms": floor,
            "x_floor": {k: v / floor for k, v in out.items()}, "rounds": len(floors),
            "returns_timed": {k: count for k, (_, count) in runs.items()},
            "batch_size_from_memory": batch_size(first.n_chirps, first.n_samples), "distinct_returns": len(recs)}


def accuracy(preset: str, per_class: int = 20, seed: int = 5) -> dict[str, object]:
    """Macro F1 per SNR of the default configuration (gated features + ensemble, open set off as in
    the run-time-against-error grid) with single-return and with batched features, same returns,
    and the largest feature difference between the two paths (relative to max(|value|, 1))."""
    from lab.bench import pareto
    from signatures.features import extract_many
    from signatures.train.evaluate import metrics
    from signatures.features import extract
    from signatures.classify.inference import load_classifier

    clf = load_classifier(preset)
    data = list(pareto._scenes(preset, SNRS, per_class, seed))
    labels = np.array([label for _, label, _, _ in data])
    snr_of = np.array([snr for snr, _, _, _ in data])
    gates = [pareto._gate_of(label, rec, truth) for _, label, rec, truth in data]
    recs = [rec for _, _, rec, _ in data]
    paths = {"single": [extract(r, g) for r, g in zip(recs, gates)], "batched": extract_many(recs, gates)}
    f1: dict[str, dict[str, float]] = {}
    for name, feats in paths.items():
        X = np.stack([f.as_array() for f in feats])
        p = clf.ensemble_proba(X)
        detected = np.array([f.detected for f in feats])
        pred = np.where(detected, np.array(clf.classes)[np.argmax(p, axis=1)], "none")
        f1[name] = {f"{s:g}": metrics(labels[snr_of == s], pred[snr_of == s], p.max(axis=1)[snr_of == s],
                                      clf.classes)["macro_f1"] for s in SNRS}
    a = np.stack([f.as_array() for f in paths["single"]]).astype(np.float64)
    b = np.stack([f.as_array() for f in paths["batched"]]).astype(np.float64)
    worst = float(np.max(np.abs(a - b) / np.maximum(np.abs(a), 1.0)))
    delta = max(abs(f1["single"][k] - f1["batched"][k]) for k in f1["single"])
    return {"macro_f1": f1, "max_f1_difference": delta, "max_feature_difference": worst, "n": len(recs)}


def registry_only(preset: str, n: int = 200, seed: int = 5) -> dict[str, float]:
    """Registry-only rejections (an unregistered serial) in batch mode (`Checker.decide`,
    then one audit transaction), per check, against the I/O floor of the same files measured in
    the same run: open + validate (`read_recording`) + SHA-256 of the file + one Cedar decision."""
    from lab.bench.decisions import UNREGISTERED, register_identities
    from lab.bench.perf import _files
    from authn.check import CheckInput, Checker, Failure
    from authn.evidence import Evidence, RegistryFacts, read_claim
    from signatures.recording import read_recording

    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'ro.sqlite3'}"
        register_identities(db)
        files = _files(Path(tmp), preset, n, seed, lambda i, slug: UNREGISTERED)
        checker = Checker(db)
        checker.check([CheckInput.file(files[0])])  # warm: policy, reader

        def batch() -> object:
            result = checker.decide([CheckInput.file(f) for f in files])
            assert result.fault is None, f"the registry-only batch stopped: {result.fault}"
            for o in result.items:  # what is timed: rejections the registry alone decides
                assert not isinstance(o, Failure), f"a registry-only check failed: {o.file}: {o.error}"
                assert o.skipped, f"a registry-only rejection ran the radar ({o.file}: {o.reasons})"
            return result

        def batch_audited() -> object:
            return checker.record(batch().items)

        rec = read_recording(files[0])
        claim = read_claim(rec, None)
        ev = Evidence(claim, RegistryFacts.of(None), int(rec.start_time.timestamp()), [])
        request = (claim.serial, ev.principal(), ev.resource(), ev.context())

        def floor() -> object:
            for f in files:
                read_recording(f)
                hashlib.sha256(Path(f).read_bytes()).hexdigest()
                checker.policy.decide_without_evidence(*request)
            return None

        times: dict[str, list[float]] = {"floor": [], "batch": [], "batch_audited": []}
        for _ in range(5):  # interleaved: the machine drifts
            for key, fn in (("floor", floor), ("batch", batch), ("batch_audited", batch_audited)):
                times[key].append(_median_ms(fn, 1) / len(files))
    med = {k: statistics.median(v) for k, v in times.items()}
    return {"io_floor_ms": med["floor"], "registry_only_ms": med["batch"],
            "registry_only_audited_ms": med["batch_audited"], "x_floor": med["batch"] / med["floor"],
            "x_floor_audited": med["batch_audited"] / med["floor"], "n": len(files)}


def plot(curves: dict[str, dict[str, object]], path: Path) -> None:
    """Per-return time against batch size (log-log), one line per preset, its FFT floor dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for i, (preset, c) in enumerate(curves.items()):
        ms = c["ms_per_return"]
        sizes = [int(k) for k in ms if k != "single"]
        colour = f"C{i}"
        ax.plot(sizes, [ms[str(s)] for s in sizes], "o-", color=colour, label=f"{preset}: batched")
        ax.axhline(ms["single"], color=colour, linestyle=":", label=f"{preset}: one return at a time")
        ax.axhline(c["fft_floor_ms"], color=colour, linestyle="--", label=f"{preset}: FFT floor")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("batch size (returns)")
    ax.set_ylabel("features + classifier, ms per return")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
