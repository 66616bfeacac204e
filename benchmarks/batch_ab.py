"""Batch time per return of this checkout against an earlier commit, interleaved in one run.

A change's cost on the batch path is a ratio of two medians, and on a shared machine only a ratio
measured in the same minutes means anything. This checks out BASE into a temporary git worktree,
starts one worker process per tree (each importing only its own tree's code, from its own
`benchmarks/batch_stages.py`: the same returns, `extract_many` and `Classifier.predict_many` as
`authn bench --batch` times), then alternates single timed rounds between them. Each worker runs
under its own tree's `authn` process settings (`authn.process.tune`, where the tree has them), as
that tree's `authn bench --batch` does; for a like-for-like ratio of the code alone, give both
trees glibc's thresholds from the environment (docs/benchmarks.md, "Batch mode").

    python benchmarks/batch_ab.py 431a2c6 --preset paper --batch 256 --rounds 25

BASE must have `benchmarks/batch_stages.py` (any commit since batch mode was measured). Each tree
simulates its returns with its own simulator, so a commit that changed the simulator times
slightly different returns: the same scenes and seeds, the same shapes.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile

#: One worker: its tree's code only (the editable install's finder removed), one warm-up round,
#: then one timed round (ms per return) per line read.
_WORKER = r"""
import sys, time
root, preset, batch = sys.argv[1], sys.argv[2], int(sys.argv[3])
def editable(f):
    return "ditable" in type(f).__name__ or "ditable" in getattr(f, "__name__", "")
sys.meta_path[:] = [f for f in sys.meta_path if not editable(f)]
sys.path[:0] = [root + "/benchmarks", root]
import numpy as np
import batch_stages as bs
import signatures
assert signatures.__file__.startswith(root), signatures.__file__
try:  # the tree's `authn` process settings, where it has them
    from authn.process import tune
except ImportError:
    pass
else:
    tune()
recs, gates = bs._returns(preset, batch)
clf = bs.load_classifier(preset)
def one():
    t0 = time.perf_counter()
    clf.predict_many(np.stack([f.as_array() for f in bs.bf.extract_many(recs, gates)]))
    return (time.perf_counter() - t0) * 1e3 / batch
one(); one()
print("ready", flush=True)
for _ in sys.stdin:
    print(f"{one():.5f}", flush=True)
"""


def _start(root: str, preset: str, batch: int) -> subprocess.Popen:
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "OMP_NUM_THREADS": "1"}
    env.pop("PYTHONPATH", None)
    p = subprocess.Popen([sys.executable, "-c", _WORKER, root, preset, str(batch)], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True, cwd=tempfile.gettempdir(), env=env)
    if p.stdout.readline().strip() != "ready":
        p.kill()
        raise SystemExit(f"batch_ab: the worker for {root} did not start (run it alone to see why)")
    return p


def interleaved(roots: dict[str, str], preset: str, batch: int, rounds: int) -> dict[str, list[float]]:
    """ms per return of each tree, one round each in turn, `rounds` times."""
    workers = {name: _start(root, preset, batch) for name, root in roots.items()}
    times: dict[str, list[float]] = {name: [] for name in roots}
    try:
        for _ in range(rounds):
            for name, p in workers.items():
                p.stdin.write("go\n")
                p.stdin.flush()
                times[name].append(float(p.stdout.readline()))
    finally:
        for p in workers.values():
            p.stdin.close()
            p.wait(timeout=60)
    return times


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("base", help="the commit to compare with (any git revision)")
    ap.add_argument("--preset", default="paper", choices=("paper", "wide"))
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--rounds", type=int, default=25)
    a = ap.parse_args(argv)
    if a.batch < 1 or a.rounds < 1:
        ap.error("--batch and --rounds must be at least 1")
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    rev = subprocess.run(["git", "-C", here, "rev-parse", "--short", a.base], capture_output=True, text=True)
    if rev.returncode != 0:
        ap.error(f"{a.base}: not a revision of this repository")
    with tempfile.TemporaryDirectory(prefix="batch-ab-") as tmp:
        tree = os.path.join(tmp, "base")
        subprocess.run(["git", "-C", here, "worktree", "add", "--detach", "-q", tree, rev.stdout.strip()], check=True)
        try:
            times = interleaved({f"base {rev.stdout.strip()}": tree, "this checkout": here}, a.preset, a.batch,
                                a.rounds)
        finally:
            subprocess.run(["git", "-C", here, "worktree", "remove", "--force", tree], check=False)
    med = {name: statistics.median(v) for name, v in times.items()}
    base, head = med.values()
    print(f"| tree | ms per return ({a.preset}, B = {a.batch}, median of {a.rounds}) |\n|---|---|")
    for name, m in med.items():
        print(f"| {name} | {m:.3f} |")
    print(f"\nthis checkout / base: {head / base:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
