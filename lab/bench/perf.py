"""Where the time goes: per-stage medians of a check, imports, the FFT floor, skipping, throughput."""

from __future__ import annotations

import math
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from lab.bench.decisions import UNREGISTERED, bench_serial, random_scene, register_identities
from authn.scenario import Broadcast, simulate_flight
from signatures.radar import get_preset
from signatures.recording import write_recording

#: Modules a cold `authn check` imports, timed one by one in fresh interpreters (onnxruntime only
#: when the cascade runs the CNN, for comparison).
COLD_IMPORTS = ("numpy", "h5py", "pydantic", "typer", "cedarpy", "pymap3d", "sqlite3", "authn.check",
                "onnxruntime")


def _fft_flops(n: int, count: int) -> float:
    """5 N log2 N real flops per complex FFT of length N (the usual radix-2 count)."""
    return 5.0 * n * math.log2(max(n, 2)) * count


def fft_floor(preset: str, gate_bins: int = 5, repeats: int = 50, dwell_divisor: int = 1) -> dict[str, float]:
    """The FFTs one gated check needs (range FFT of the cube, Doppler FFT of the gate, STFT of
    the gate), their flop count, and numpy's time for exactly those transforms; of the first
    1/`dwell_divisor` of the dwell when a configuration uses only that."""
    from signatures.dsp import timefreq as tf

    pre = get_preset(preset)
    n, k = max(1, pre.n_chirps // dwell_divisor), pre.n_samples
    win, hop = tf.stft_params(pre.config, n)
    frames = (n - win) // hop + 1
    flops = _fft_flops(k, n) + _fft_flops(n, gate_bins) + _fft_flops(win, frames * gate_bins)
    rng = np.random.default_rng(0)
    cube = (rng.standard_normal((n, k)) + 1j * rng.standard_normal((n, k))).astype(np.complex128)
    gate = cube[:, :gate_bins].copy()
    stft = np.ascontiguousarray(np.lib.stride_tricks.sliding_window_view(gate, win, axis=0)[::hop])
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.fft.fft(cube, axis=1)
        np.fft.fft(gate, axis=0)
        np.fft.fft(stft, axis=-1)
        times.append((time.perf_counter() - t0) * 1e3)
    ms = statistics.median(times)
    return {"fft_mflop": flops / 1e6, "fft_ms": ms, "gflops": flops / (ms * 1e6)}


def _files(tmp: Path, preset: str, n: int, seed: int, serial_for) -> list[Path]:
    rng = np.random.default_rng(seed)
    pre = get_preset(preset)
    now = datetime.now(timezone.utc)
    out = []
    for i in range(n):
        slug = ("m600", "m300", "phantom4")[i % 3]
        scene, az = random_scene(rng, slug, (10.0, 30.0))
        rec, _ = simulate_flight(scene, pre, i, Broadcast(serial=serial_for(i, slug)), azimuth_deg=az,
                                 start_time=now)
        out.append(write_recording(rec, tmp / f"{preset}-{i:04d}.h5"))
    return out


MIX = ("genuine", "genuine", "genuine", "type_spoof", "position_spoof", "unregistered", "revoked")


def _mixed_serial(i: int, slug: str) -> str:
    kind = MIX[i % len(MIX)]
    if kind == "unregistered":
        return UNREGISTERED
    if kind == "revoked":
        return bench_serial(slug, revoked=True)
    if kind == "type_spoof":
        return bench_serial({"m600": "m300", "m300": "phantom4", "phantom4": "m600"}[slug])
    return bench_serial(slug)


def stage_table(preset: str, n: int, seed: int) -> dict[str, object]:
    """Per-stage medians over a realistic mix of claims (batch mode), and the skip statistics.

    Mix: 3/7 genuine, 1/7 each type spoof, position spoof, unregistered, revoked. Check
    times exclude the audit write, which is shown per check for a batched transaction and
    for a single one.
    """
    from authn.check import Checker

    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'perf.sqlite3'}"
        register_identities(db)
        files = _files(Path(tmp), preset, n, seed, _mixed_serial)
        checker = Checker(db)
        checker.record([checker.evaluate(files[0])])  # warm-up: models loaded once
        stages: dict[str, list[float]] = defaultdict(list)
        totals: dict[str, list[float]] = {"full": [], "skipped": []}
        skipped_counts: dict[str, int] = defaultdict(int)
        outcomes = []
        for f in files:
            t0 = time.perf_counter()
            o = checker.evaluate(f)
            totals["skipped" if o.radar is None else "full"].append((time.perf_counter() - t0) * 1e3)
            for k, v in o.timings_ms.items():
                stages[k].append(v)
            for s in o.skipped:
                skipped_counts[s] += 1
            outcomes.append(o)
        t0 = time.perf_counter()
        checker.record(outcomes)  # batch mode: one transaction for the batch
        stages["audit (batched, per check)"] = [(time.perf_counter() - t0) * 1e3 / len(outcomes)]
        t0 = time.perf_counter()
        checker.record([outcomes[0]])
        stages["audit (one transaction)"] = [(time.perf_counter() - t0) * 1e3]
    med = {k: statistics.median(v) for k, v in stages.items()}
    full = statistics.median(totals["full"]) if totals["full"] else float("nan")
    fast = statistics.median(totals["skipped"]) if totals["skipped"] else float("nan")
    saved = statistics.median(stages.get("radar_features", [0.0])) + statistics.median(stages.get("classify", [0.0]))
    return {"stage_median_ms": med, "checks": n, "radar_time_saved_per_skip_ms": saved,
            "skip_share": {k: v / n for k, v in skipped_counts.items()},
            "full_check_ms": full, "registry_only_check_ms": fast,
            "registry_only_vs_full": fast / full if full == full and full else float("nan")}


def import_costs(repeats: int = 3) -> dict[str, float]:
    """Median wall time of `python -c 'import X'` per module, and of the bare interpreter."""
    def run(code: str) -> float:
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
            ts.append((time.perf_counter() - t0) * 1e3)
        return statistics.median(ts)

    out = {"python -c pass": run("pass")}
    for mod in COLD_IMPORTS:
        out[f"import {mod}"] = run(f"import {mod}")
    return out


def _worker(args: tuple[str, list[str]]) -> int:
    db, paths = args
    from authn.check import Checker
    from authn.process import tune

    tune()  # a spawned interpreter stands for an `authn` process

    checker = Checker(db)
    for p in paths:
        checker.record([checker.evaluate(p)])
    return len(paths)


def _ignore_ctrl_c() -> None:
    """In a spawned worker: Ctrl-C reaches the whole process group, but stopping is the parent's
    to do (`authn bench` ends its workers), so the worker prints no traceback of its own. SIGTERM
    keeps its default: it is how the pool ends its workers."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def throughput(preset: str, n: int, seed: int) -> dict[str, float]:
    """Returns per second in batch mode with 1 and 2 worker processes (models loaded once per worker)."""
    import multiprocessing as mp

    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'tp.sqlite3'}"
        register_identities(db)
        files = [str(f) for f in _files(Path(tmp), preset, n, seed, lambda i, slug: bench_serial(slug))]
        ctx = mp.get_context("spawn")
        for workers in (1, 2):
            chunks = [files[i::workers] for i in range(workers)]
            with ctx.Pool(workers, initializer=_ignore_ctrl_c) as pool:
                pool.map(_worker, [(db, c[:2]) for c in chunks])  # start-up and model load, not timed
                t0 = time.perf_counter()
                done = sum(pool.map(_worker, [(db, c) for c in chunks]))
                out[f"{workers}_worker"] = done / (time.perf_counter() - t0)
    return out
