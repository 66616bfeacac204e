"""The client side of `authn check ARCHIVE --cluster`: cut the files into partitions, run
them on the workers (authn.cluster.worker), stream each partition's results as it
finishes (a progress bar on stderr), and summarise: counts, throughput, exit code.

Every printed result is committed: a worker appends its partition in one audit
transaction before returning it. A partition whose worker dies is re-run by the
scheduler; its idempotency key makes the re-run append nothing when the first run had
committed. A partition that fails every retry gets error entries from the client."""

from __future__ import annotations

import json
import sys
import time
import uuid
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from authn.cluster.worker import CheckerArgs, Partition, PartitionResult, check_partition, record_lost
from core.textsafe import printable

#: Default partitions per worker: enough to balance uneven files and to bound what a lost
#: worker's retry re-does, few enough that one audit transaction per partition stays cheap.
PARTITIONS_PER_WORKER = 4
MAX_PARTITION = 250


def partition_size_for(n_files: int, workers: int) -> int:
    """About PARTITIONS_PER_WORKER partitions per worker, at most MAX_PARTITION files each."""
    return max(1, min(MAX_PARTITION, -(-n_files // (PARTITIONS_PER_WORKER * max(workers, 1)))))


def plan(paths: Sequence[Path], claims: Sequence[str | None], size: int, run_id: str | None = None
         ) -> list[Partition]:
    """Partitions of `size` files in order; keys name the run (a fresh id unless given)."""
    run_id = run_id or uuid.uuid4().hex
    files = [str(Path(p).resolve()) for p in paths]  # workers may run in another directory
    return [Partition(f"check/{run_id}/{i}", tuple(files[a:a + size]), tuple(claims[a:a + size]))
            for i, a in enumerate(range(0, len(files), size))]


def run_partitions(client: Any, checker: Any, args: CheckerArgs, parts: Sequence[Partition]
                   ) -> Iterator[PartitionResult]:
    """Each partition's result as it finishes (any order). A task that fails after its
    retries becomes error entries written here; unfinished tasks are cancelled if the
    caller stops early."""
    from distributed import as_completed

    from authn.cluster.engine import RETRIES
    from core.errors import describe

    futures = {client.submit(check_partition, args, p, key=f"authn-{p.key.replace('/', '-')}", retries=RETRIES,
                             pure=False): p for p in parts}
    try:
        for fut in as_completed(futures):
            try:
                yield fut.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, a database fault on every retry, ...
                yield record_lost(checker, futures[fut], describe(exc))
    finally:
        client.cancel(list(futures))


@dataclass
class Summary:
    total: int
    workers: int
    partitions: int
    seconds: float = 0.0
    codes: list[int] = field(default_factory=list)
    replayed: int = 0  # partitions found committed by a re-run

    @property
    def throughput(self) -> float:
        return len(self.codes) / self.seconds if self.seconds > 0 else 0.0

    @property
    def exit_code(self) -> int:
        """The worst one, as in batch mode (3 > 2 > 1 > 4 > 0)."""
        from core.errors import worst

        return worst(self.codes)

    def line(self) -> str:
        accepted, rejected, unsure = self.codes.count(0), self.codes.count(1), self.codes.count(4)
        errors = len(self.codes) - accepted - rejected - unsure
        return (f"{self.total} returns: {accepted} accepted, {rejected} rejected, {unsure} inconclusive, "
                f"{errors} errors in "
                f"{self.seconds:.1f} s ({self.throughput:.1f} returns/s on {self.workers} workers, "
                f"{self.partitions} partitions" + (f", {self.replayed} found committed on re-run" if self.replayed
                                                   else "") + ")")


def recheck(checker: Any, args: CheckerArgs, paths: Sequence[Path], claims: Sequence[str | None], address: str,
            partition_size: int | None = None, as_json: bool = False, out: TextIO | None = None) -> Summary:
    """Re-check `paths` on the cluster at `address`; prints as `authn check DIR` does (a
    JSON array streamed with --json, else a summary line) and returns the summary."""
    from rich.console import Console
    from rich.progress import Progress

    from authn.cluster.engine import connect, n_workers
    from core.errors import EXIT_BAD_INPUT, EXIT_SYSTEM

    out = out or sys.stdout
    first = True
    with connect(address) as client:
        workers = n_workers(client)
        parts = plan(paths, claims, partition_size or partition_size_for(len(paths), workers))
        summary = Summary(len(paths), workers, len(parts))
        t0 = time.perf_counter()
        with Progress(transient=True, disable=as_json and not sys.stderr.isatty(),
                      console=Console(stderr=True)) as progress:
            task = progress.add_task(f"checking {len(paths)} returns on {workers} workers", total=len(paths))
            for result in run_partitions(client, checker, args, parts):
                summary.replayed += result.replayed
                summary.codes.extend(result.codes)
                if as_json and result.texts:  # the JSON array of batch mode, streamed as partitions commit
                    out.write(("[\n" if first else ",\n") + ",\n".join(result.texts))
                    first = False
                for text, code in zip(result.texts, result.codes):
                    if code in (EXIT_BAD_INPUT, EXIT_SYSTEM):  # 4 is a decision: inconclusive
                        doc = json.loads(text)
                        print(printable(f"error: {doc['file']}: {doc['error']}"), file=sys.stderr)
                out.flush()
                progress.advance(task, len(result.codes))
        summary.seconds = time.perf_counter() - t0
    if as_json:
        out.write(("[" if first else "\n") + "]\n")
    print(summary.line(), file=sys.stderr if as_json else out)
    return summary


def cli_recheck(checker: Any, paths: Sequence[Path], mapping: dict[str, str], serial: str | None, address: str,
                partition_size: int | None, as_json: bool, *, policy: Path | None,
                trusted: dict[bytes, bytes] | None, model: Path | None) -> int:
    """`authn check ... --cluster`: the options as the workers need them; returns the exit code."""
    sprt = checker.sprt
    args = CheckerArgs(checker.db.url, str(policy.resolve()) if policy else None,
                       tuple(sorted((trusted or {}).items())), str(model.resolve()) if model else None,
                       None if sprt is None else (sprt.false_accept, sprt.false_reject))
    claims = [mapping.get(p.name, mapping.get(str(p), serial)) for p in paths]
    return recheck(checker, args, paths, claims, address, partition_size, as_json).exit_code
