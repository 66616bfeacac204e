"""How long training and enrolment take on this machine, from a short timed calibration.

Simulating the returns dominates both (`models train --like` on a 4096-pulse CW waveform: about
95 % of the wall time); the rest is fitting forests. A pace measured in the main process alone and
divided by the worker count assumes the workers run in parallel at full speed, which a machine
shared with other work does not give (2 workers on 2 busy cores: 2x slower than that). So the
simulation is timed on the very pool layout that will run it: each worker warmed up with one
return (imports, FFT plans), then a few returns on every worker at once, the wall time over the
returns. Forests are timed the same way: one fit on a small sample, scaled by n log n.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

__all__ = ["PER_WORKER", "Pace", "fit_seconds", "pace", "scale", "seconds"]

#: Returns each worker simulates for the timing (after one to warm it up): 4 x 2 workers cover the
#: five classes of a dataset (a bird or an empty scene is cheaper than an airframe).
PER_WORKER = 4


@dataclass(frozen=True)
class Pace:
    """Wall seconds per return with `workers` simulating at once, measured on `timed` returns."""

    seconds_per_return: float
    timed: int
    workers: int


def pace(spec: Any, workers: int, per_worker: int = PER_WORKER, clock: Callable[[], float] = time.perf_counter,
         pool: Callable[[int], Executor] = ProcessPoolExecutor) -> Pace:
    """The simulation's pace for `spec` (`signatures.train.dataset.DatasetSpec`) on `workers` processes:
    one warm-up return per worker, then `per_worker` returns on each, all at once (scenes past the
    warm-up ones: a scene's draw does not depend on `spec.n`)."""
    from signatures.train.dataset import _chunk, default_featurizer

    featurizer = default_featurizer()
    with pool(workers) as ex:
        for f in [ex.submit(_chunk, spec, featurizer, i, i + 1) for i in range(workers)]:
            f.result()
        start = workers
        t0 = clock()
        jobs = [ex.submit(_chunk, spec, featurizer, start + w * per_worker, start + (w + 1) * per_worker)
                for w in range(workers)]
        for f in jobs:
            f.result()
        wall = clock() - t0
    n = workers * per_worker
    return Pace(wall / n, n, workers)


def fit_seconds(n_rows: int, n_features: int, seed: int = 0, clock: Callable[[], float] = time.perf_counter,
                sample: int = 300) -> float:
    """Seconds one site forest (`signatures.train.classifiers.make_rf`) takes on `n_rows` rows: timed on
    `sample` random rows, scaled by n log n (a tree's sort of each node's rows)."""
    import numpy as np

    from signatures.train.classifiers import make_rf

    rng = np.random.default_rng(seed)
    m = min(sample, max(n_rows, 2))
    X = rng.normal(size=(m, n_features))
    y = np.arange(m) % 5
    t0 = clock()
    make_rf(seed).fit(X, y)
    took = clock() - t0
    return took * scale(n_rows, m)


def scale(n: int, m: int) -> float:
    """n log n over m log m: how a forest's fit grows from m rows to n."""
    n, m = max(n, 2), max(m, 2)
    return (n * math.log(n)) / (m * math.log(m))


def seconds(returns: int, p: Pace, fits: int = 0, per_fit_s: float = 0.0) -> float:
    """The estimate: the returns at the measured pace (the workers' parallelism is in it), plus
    the forests' fits."""
    return returns * p.seconds_per_return + fits * per_fit_s
