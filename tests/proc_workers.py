"""Run a function in several spawned processes released together (concurrency tests)."""

from __future__ import annotations

import multiprocessing as mp


def _call(fn, args, barrier, results, i) -> None:
    try:
        results.put((i, fn(*args, barrier)))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent test, not swallowed
        results.put((i, exc))


def run_in_processes(fn, arg_lists: list[tuple], timeout_s: float = 300) -> list:
    """Run fn(*args, barrier) in one spawned process per arg tuple, released together."""
    ctx = mp.get_context("spawn")
    barrier, results = ctx.Barrier(len(arg_lists)), ctx.Queue()
    procs = [ctx.Process(target=_call, args=(fn, a, barrier, results, i))
             for i, a in enumerate(arg_lists)]
    for p in procs:
        p.start()
    out = dict(results.get(timeout=timeout_s) for _ in procs)
    for p in procs:
        p.join(30)
    errors = [r for r in out.values() if isinstance(r, BaseException)]
    if errors:
        raise errors[0]
    return [out[i] for i in range(len(procs))]


def check_many(url: str, path: str, serials: list[str], barrier) -> list[int]:
    """Run one full `authn check` evaluation + audit append (one transaction) per serial."""
    from authn.check import Checker

    checker = Checker(url)
    barrier.wait()
    ids = []
    for serial in serials:
        ids.extend(checker.record([checker.evaluate(path, serial)]))
    return ids
