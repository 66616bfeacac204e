"""Training and enrolment estimates come from a timed calibration on the worker pool that does the
work (`signatures.train.eta`), not from a constant or a one-process pace divided by the worker count: the
formula, with a fake clock and a fake pool (no timing is asserted)."""

from __future__ import annotations

from concurrent.futures import Future

import pytest

from signatures.train.eta import Pace, pace, scale, seconds


class _Pool:
    """Runs nothing: records each chunk (start, stop) it is given; a context manager like a pool."""

    def __init__(self, workers: int) -> None:
        self.workers, self.chunks = workers, []
        _Pool.last = self

    def __enter__(self) -> "_Pool":
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def submit(self, fn, spec, featurizer, start: int, stop: int) -> Future:
        self.chunks.append((start, stop))
        done: Future = Future()
        done.set_result(None)
        return done


def test_the_pace_is_the_pool_s_wall_time_per_return_after_a_warm_up() -> None:
    from signatures.train.dataset import DatasetSpec
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset

    spec = DatasetSpec(preset=get_preset("cw-sband"), profiles=tuple(shipped_profiles().values()), split="train", n=10)
    ticks = iter([100.0, 100.8])  # the clock read before and after the timed chunks only
    p = pace(spec, 2, per_worker=2, clock=lambda: next(ticks), pool=_Pool)
    assert p == Pace(seconds_per_return=pytest.approx(0.2), timed=4, workers=2)
    assert _Pool.last.chunks == [(0, 1), (1, 2), (2, 4), (4, 6)]  # one warm-up each, then 2 each at once


def test_the_estimate_is_returns_at_that_pace_plus_the_fits() -> None:
    p = Pace(seconds_per_return=0.2, timed=4, workers=2)
    assert seconds(3575, p) == pytest.approx(715.0)  # the workers' parallelism is inside the pace
    assert seconds(100, p, fits=6, per_fit_s=1.5) == pytest.approx(29.0)
    assert scale(300, 300) == 1.0 and scale(3000, 300) == pytest.approx(10 * 8.0064 / 5.7038, rel=1e-3)


def test_a_long_training_run_says_why() -> None:
    from authn.cli.models import _why_slow

    p = Pace(seconds_per_return=0.2, timed=4, workers=2)
    why = _why_slow(715.0, 3575, 2000, p)
    assert why.startswith("over a minute: simulating the 3575 returns dominates (each 200 ms")
    assert "(2000 now)" in why and "--samples" in why
    assert _why_slow(45.0, 200, 150, p) == ""
