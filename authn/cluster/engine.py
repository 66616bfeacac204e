"""The Dask connection: `local` starts a LocalCluster (one single-threaded worker process per
core), anything else is a scheduler address. Also the hook that runs training-set chunks
on the cluster."""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from core.errors import AuthnError, SystemFault

#: Seconds to wait for a remote scheduler before giving up (exit 3).
CONNECT_TIMEOUT_S = 30
#: Times a task that raised is re-run; a task whose worker died is re-run by the scheduler
#: itself (`distributed.scheduler.allowed-failures`, 3 by default).
RETRIES = 2
#: Dask settings of a local cluster's workers (set the same on the workers of a real cluster,
#: docs/cluster.md):
#: - the statistical profiler samples every task's stack every 10 ms under the GIL: 15-25 % of
#:   a worker's CPU time on a re-check (measured), and we never read its profiles;
#: - the nanny's MALLOC_TRIM_THRESHOLD_=65536 (set by Dask in every worker it spawns, to hand
#:   freed memory back to the OS early) is left unset: setting it freezes glibc's mmap threshold
#:   at 128 KiB, so every array larger than that (the batch's cubes, spectra, workspaces) is a
#:   fresh mapping whose pages fault in on every use: on a 2,000-return re-check, 10x the
#:   minor page faults of one process and +30-50 % CPU per worker (measured);
#: - Dask's housekeeping runs less often: the event-loop tick (20 ms: it only times the loop to
#:   warn when it was blocked), the memory monitors of workers and nannies (100 ms: they act on
#:   memory limits, which a re-check's fixed-size partitions do not approach) and the system
#:   monitor (500 ms: the dashboard's CPU and disk plots). An idle local cluster of 2 workers
#:   uses 1.0 s of CPU per 20 s (client 0.5, each worker 0.27) with the defaults, 0.22 s
#:   with these: ~2 % of a 2-core machine during a re-check (measured).
LOCAL_CONFIG = {"distributed.worker.profile.enabled": False,
                "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                "distributed.admin.tick.interval": "1s",
                "distributed.worker.memory.monitor-interval": "1s",
                "distributed.admin.system-monitor.interval": "2s",
                "distributed.admin.system-monitor.disk": False}


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise SystemFault("--cluster needs Dask distributed: pip install 'uav-radar-authn[cluster]'") from None
    return distributed


@contextmanager
def connect(address: str, workers: int | None = None) -> Iterator[Any]:
    """A `distributed.Client` for `address` ("local", or e.g. tcp://scheduler:8786), closed
    after the block (a local cluster is shut down with it)."""
    distributed = _distributed()
    if address == "local":
        import dask

        n = workers or os.cpu_count() or 1
        with (dask.config.set(LOCAL_CONFIG),
              distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                                       silence_logs=logging.CRITICAL) as cluster,
              distributed.Client(cluster) as client):
            yield client
        return
    if "://" not in address and ":" not in address:
        raise AuthnError(f"--cluster {address!r}: give 'local' or a scheduler address such as tcp://host:8786")
    try:
        client = distributed.Client(address, timeout=CONNECT_TIMEOUT_S)
    except (OSError, TimeoutError, ValueError) as exc:
        raise SystemFault(f"cannot reach the Dask scheduler at {address}: {' '.join(str(exc).split())}") from None
    with client:
        yield client


def n_workers(client: Any) -> int:
    """Worker processes connected now."""
    return len(client.nthreads())


@contextmanager
def training_on(address: str) -> Iterator[None]:
    """Inside the block every training-set `generate` runs its chunks as tasks on the cluster."""
    from signatures.train.dataset import chunks_on

    with connect(address) as client, chunks_on(client.get_executor(retries=RETRIES)):
        yield
