"""What a check costs against the work it cannot avoid: the three targets of docs/benchmarks.md
("The cost of a check"), each measured in this one run.

* **batch**: `authn check DIR --json` of N `paper` returns (genuine claims of the shipped
  models, so every return runs the radar), in process (the command's own chunked loop,
  `authn.cli.check._batch`, every chunk audited before it is printed) and end to end (a fresh
  `python -m authn` process), against the **floor** of the same files: `read_recording`
  (open, validate, read) + SHA-256 of the bytes + the FFTs of one gated check (the range FFT of
  the cube, the Doppler FFT and the STFT of a 5-bin gate, numpy). In process and floor rounds
  are interleaved; medians.
* **cold**: `python -m authn check FILE --json`, the same without `--json` (the human output)
  and `python -c "import numpy"`, each a fresh process, taking turns, after `compileall` of the
  tree (as a wheel installs it); medians.
* **audit**: the audit stage of those cold checks (`timings_ms.audit` of the JSON).

    python benchmarks/check_cost.py [--n 200] [--rounds 5] [--cold 9]

Everything it writes (files, database, log key, STH log, HOME) goes to a temporary folder.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this tree's code, ahead of any installed copy


def _env(tmp: Path) -> dict[str, str]:
    """A child's environment: the authn paths and HOME in `tmp`, this tree first on the path."""
    env = {**os.environ, "HOME": str(tmp), "AUTHN_LOG_KEY": str(tmp / "log.pem"),
           "AUTHN_AUDIT_STH_LOG": str(tmp / "sth.jsonl"), "AUTHN_DATABASE_URL": f"sqlite:///{tmp / 'reg.sqlite3'}",
           "PYTHONPATH": str(ROOT)}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _files(tmp: Path, n: int) -> list[Path]:
    from lab.bench.decisions import bench_serial, register_identities
    from lab.bench.perf import _files as simulated

    register_identities(f"sqlite:///{tmp / 'reg.sqlite3'}")
    folder = tmp / "returns"
    folder.mkdir()
    return simulated(folder, "paper", n, 5, lambda i, slug: bench_serial(slug))


def floor(files: list[Path]) -> None:
    """Read + validate, hash and transform each file: the work no check of it avoids."""
    import numpy as np

    from signatures.dsp import timefreq as tf
    from signatures.recording import read_recording

    for f in files:
        rec = read_recording(f)
        hashlib.sha256(f.read_bytes()).hexdigest()
        np.fft.fft(rec.iq, axis=1)
        gate = rec.iq[:, :5]
        win, hop = tf.stft_params(rec.config, rec.n_chirps)
        np.fft.fft(gate, axis=0)
        np.fft.fft(np.lib.stride_tricks.sliding_window_view(gate, win, axis=0)[::hop], axis=-1)


def batch(checker, files: list[Path]) -> list:
    """`authn check DIR --json` in process: the command's chunked loop, its JSON captured."""
    import typer

    from authn.cli.check import _batch

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            _batch(checker, files, {}, None, True)
        except typer.Exit:
            pass
    return json.loads(out.getvalue())


def _ms(fn, *args) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return (time.perf_counter() - t0) * 1e3


def batch_cost(tmp: Path, files: list[Path], rounds: int) -> dict[str, float]:
    from authn.check import Checker
    from authn.process import tune

    tune()
    os.environ.update({k: v for k, v in _env(tmp).items() if k.startswith("AUTHN_")})
    checker = Checker(os.environ["AUTHN_DATABASE_URL"])
    decisions = {d["decision"] for d in batch(checker, files)}  # warm: models, workspaces, the allocator
    floor(files)
    times: dict[str, list[float]] = {"floor": [], "batch": []}
    for _ in range(rounds):
        times["floor"].append(_ms(floor, files) / len(files))
        times["batch"].append(_ms(batch, checker, files) / len(files))
    cmd = [sys.executable, "-m", "authn", "check", str(files[0].parent), "--json"]
    env = _env(tmp)
    e2e = [_ms(lambda: subprocess.run(cmd, capture_output=True, env=env, cwd=ROOT)) / len(files) for _ in range(2)]
    med = {k: statistics.median(v) for k, v in times.items()}
    return {"floor_ms": med["floor"], "batch_ms": med["batch"], "end_to_end_ms": min(e2e),
            "batch_x": med["batch"] / med["floor"], "end_to_end_x": min(e2e) / med["floor"],
            "decisions": sorted(decisions)}


def cold_cost(tmp: Path, file: Path, runs: int) -> dict[str, float]:
    subprocess.run([sys.executable, "-m", "compileall", "-q", "authn", "core", "registry", "signatures", "remoteid"],
                   cwd=ROOT, check=False, capture_output=True)
    env = _env(tmp)
    cmds = {"numpy": [sys.executable, "-c", "import numpy"],
            "json": [sys.executable, "-m", "authn", "check", str(file), "--json"],
            "human": [sys.executable, "-m", "authn", "check", str(file)]}
    times: dict[str, list[float]] = {k: [] for k in cmds}
    audit: list[float] = []
    for i in range(runs + 1):  # the first round warms the page cache
        for name, cmd in cmds.items():
            t0 = time.perf_counter()
            p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
            ms = (time.perf_counter() - t0) * 1e3
            if p.returncode not in (0, 1, 4):
                raise SystemExit(f"check_cost: {' '.join(cmd)} exited {p.returncode}: {p.stderr.strip()}")
            if i:
                times[name].append(ms)
                if name == "json":
                    audit.append(float(json.loads(p.stdout)["timings_ms"]["audit"]))
    med = {k: statistics.median(v) for k, v in times.items()}
    return {"numpy_ms": med["numpy"], "json_ms": med["json"], "human_ms": med["human"],
            "json_x_numpy": med["json"] / med["numpy"], "human_x_json": med["human"] / med["json"],
            "audit_ms": statistics.median(audit), "audit_max_ms": max(audit)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=200, help="returns in the batch (default 200)")
    ap.add_argument("--rounds", type=int, default=5, help="interleaved batch rounds (default 5)")
    ap.add_argument("--cold", type=int, default=9, help="cold runs of each command (default 9)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of lines")
    args = ap.parse_args(argv)
    if min(args.n, args.rounds, args.cold) < 1:
        ap.error("--n, --rounds and --cold must be >= 1")
    with tempfile.TemporaryDirectory(prefix="authn-check-cost-") as t:
        tmp = Path(t)
        files = _files(tmp, args.n)
        cold = cold_cost(tmp, files[0], args.cold)
        result = {"n": args.n, "batch": batch_cost(tmp, files, args.rounds), "cold": cold}
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    b = result["batch"]
    print(f"batch of {args.n} paper returns: floor (read + hash + FFT) {b['floor_ms']:.3f} ms per return; "
          f"in process {b['batch_ms']:.3f} ms = {b['batch_x']:.2f}x; end to end {b['end_to_end_ms']:.3f} ms = "
          f"{b['end_to_end_x']:.2f}x; decisions {', '.join(b['decisions'])}")
    print(f"cold check: import numpy {cold['numpy_ms']:.0f} ms; --json {cold['json_ms']:.0f} ms = "
          f"{cold['json_x_numpy']:.2f}x; human {cold['human_ms']:.0f} ms = {cold['human_x_json']:.3f}x of --json")
    print(f"audit stage of the cold check: median {cold['audit_ms']:.2f} ms, max {cold['audit_max_ms']:.2f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
