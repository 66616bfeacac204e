"""Where a batch's time goes, and the part of it no implementation of these features avoids.

Two tables for one preset, both per return and as multiples of the FFT floor measured in the
same run (`lab.bench.perf.fft_floor`, as `authn bench --batch`; docs/benchmarks.md, "Batch mode"):

* **stages**: `extract_many` + `Classifier.predict_many` on a batch of B of the bench's returns
  (`lab.bench.batch.curve`'s scenes), with the batch path's stage functions wrapped in timers
  (cube stage, sub-chirp bins, flash series, periodicity, spectrogram, cadence, the rest of the
  slow stage, the classifier); medians over rounds.
* **transforms alone**: on random cubes of the preset's shape, in the batch path's precision
  (complex64, scipy's transforms, one thread): the cube's passes every check needs (slow-time
  mean, clutter subtraction, window, range FFT, range profile), the sub-chirp products as one
  matrix product over the batch (where the waveform has sub-chirp windows), the gate's Doppler FFT
  and its STFT. What is left of a target ratio after these is all the estimators may cost.

It runs under the `authn` process's settings (`authn.process.tune`: the GC and glibc's memory
thresholds), as `authn bench --batch` does; the header line counts the minor page faults (fresh
memory's first touches) per return.

    python benchmarks/batch_stages.py --preset paper --batch 256
    python benchmarks/batch_stages.py --preset wide --batch 64 --json
"""

from __future__ import annotations

import argparse
import functools
import json
import statistics
import time
from collections.abc import Callable

import numpy as np

from authn.process import tune
from lab.bench import perf
from lab.bench.batch import _median_ms, returns
from signatures.dsp import extraction as bf
from signatures import features as F
from signatures.dsp import flash_period, flash_series
from signatures.dsp import rd
from signatures.dsp import timefreq as tf
from signatures.classify.inference import load_classifier
from signatures.radar import get_preset
from signatures.dsp.threads import one_blas_thread

#: (module, function) wrapped in timers, reported under the function's name
STAGES = ((bf, "_cube_stage"), (bf, "_subchirp_bins"), (flash_series, "flash_series_batch"),
          (flash_period, "periodicity_batch"), (bf, "_spectrogram"), (bf, "_cadence"), (bf, "_slow_stage"))


def _returns(preset: str, batch: int) -> tuple[list, list]:
    """The batch bench's 60 returns (`lab.bench.batch.returns`), repeated to fill `batch` rows."""
    recs, gates = returns(preset)
    rows = [i % len(recs) for i in range(batch)]
    return [recs[i] for i in rows], [gates[i] for i in rows]


def _minor_faults() -> int:
    """Pages this process has faulted in so far (fresh memory's first touches)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def stages(preset: str, batch: int, rounds: int) -> tuple[dict[str, float], float]:
    """Median ms per return of each stage (and 'classifier', 'total') over `rounds` batches, and
    the mean minor page faults per return ('page faults')."""
    clf = load_classifier(preset)
    recs, gates = _returns(preset, batch)
    spent: dict[str, float] = {}
    originals = [(mod, name, getattr(mod, name)) for mod, name in STAGES]

    def timed(name: str, fn: Callable) -> Callable:
        @functools.wraps(fn)
        def run(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[name] = spent.get(name, 0.0) + time.perf_counter() - t0
        return run

    for mod, name, fn in originals:
        setattr(mod, name, timed(name, fn))
    try:
        per_round: list[dict[str, float]] = []
        for r in range(rounds + 1):  # the first round warms workspaces and models
            if r == 1:
                faults = _minor_faults()
            spent.clear()
            t0 = time.perf_counter()
            features = np.stack([f.as_array() for f in bf.extract_many(recs, gates)])
            t1 = time.perf_counter()
            clf.predict_many(features)
            t2 = time.perf_counter()
            if r:
                per_round.append(dict(spent, classifier=t2 - t1, total=t2 - t0))
        faults = (_minor_faults() - faults) / (rounds * batch)
    finally:
        for mod, name, fn in originals:
            setattr(mod, name, fn)
    out = {k: statistics.median(p.get(k, 0.0) for p in per_round) * 1e3 / batch for k in per_round[0]}
    inner = ("flash_series_batch", "periodicity_batch", "_spectrogram", "_cadence")  # called by _slow_stage
    out["rest of the slow stage"] = out["_slow_stage"] - sum(out.get(k, 0.0) for k in inner)
    return out, faults


def transforms(preset: str, batch: int, rounds: int) -> dict[str, float]:
    """Median ms per return of the transforms every check of `preset` makes, alone (module docstring)."""
    import scipy.fft as sfft

    pre = get_preset(preset)
    n, k = pre.n_chirps, pre.n_samples
    rng = np.random.default_rng(0)
    rows = min(batch, max(1, bf._CUBE_BLOCK_BYTES // (8 * n * k)))  # the cube stage's block of rows
    cube = (rng.standard_normal((rows, n, k)) + 1j * rng.standard_normal((rows, n, k))).astype(np.complex64)
    window = rd.hann(k).astype(np.float32)
    work = np.empty_like(cube)
    gate = np.ascontiguousarray(cube[:, :, :F.GATE_BINS])
    hann_slow = rd.hann(n).astype(np.float32)[:, None]
    win, hop = tf.stft_params(pre.config, n)
    frames = np.ascontiguousarray(np.lib.stride_tricks.sliding_window_view(gate, win, axis=1)[:, ::hop])
    sub = flash_series.subchirp_window(pre.config, k)

    def cube_passes() -> None:
        np.subtract(cube, cube.mean(axis=1, keepdims=True), out=work)
        np.multiply(work, window, out=work)
        spec = sfft.fft(work, axis=-1, overwrite_x=True, workers=1)
        f = spec.view(np.float32)
        np.einsum("bnj,bnj->bj", f, f)

    parts: dict[str, Callable[[], object]] = {"cube passes + range FFT": cube_passes}
    if sub:
        basis = flash_series.scaled_subchirp_basis(k, k // 4, sub, np.complex64)
        parts["sub-chirp products"] = lambda: cube.reshape(-1, k) @ basis
    parts["Doppler FFT"] = lambda: sfft.fft(gate * hann_slow, axis=1, workers=1)
    parts["STFT"] = lambda: sfft.fft(frames, axis=-1, workers=1)
    out = {}
    with one_blas_thread():
        for name, fn in parts.items():
            fn()
            out[name] = _median_ms(fn, max(3, rounds)) / rows
    out["total"] = sum(out.values())
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="paper", choices=("paper", "wide"))
    ap.add_argument("--batch", type=int, default=256, help="rows per batch (default 256)")
    ap.add_argument("--rounds", type=int, default=10, help="timed rounds, medians (default 10)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of tables")
    args = ap.parse_args(argv)
    if args.batch < 1 or args.rounds < 1:
        ap.error("--batch and --rounds must be >= 1")
    tune()
    floor = perf.fft_floor(args.preset, repeats=20)["fft_ms"]
    staged, faults = stages(args.preset, args.batch, args.rounds)
    result = {"preset": args.preset, "batch": args.batch, "fft_floor_ms": floor, "stages_ms": staged,
              "page_faults_per_return": faults,
              "transforms_ms": transforms(args.preset, args.batch, args.rounds)}
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(f"{args.preset}, batch {args.batch}, FFT floor {floor:.3f} ms per return, "
          f"{faults:.1f} page faults per return")
    for title, table in (("stage", result["stages_ms"]), ("transform alone", result["transforms_ms"])):
        print(f"\n| {title} | ms per return | x floor |\n|---|---|---|")
        for name, ms in table.items():
            print(f"| {name.strip('_')} | {ms:.3f} | {ms / floor:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
