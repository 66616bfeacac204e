"""What runs on a Dask worker for `authn check --cluster`: check one partition of files and
append its decisions in ONE audit transaction keyed by (run id, partition index).

Exactly once: a partition re-run after its worker died (the scheduler re-runs the task)
first asks whether its key committed: if so it returns those entries without checking
again; if not, it checks the files and appends, and `authn.audit.append` refuses inside
the transaction to append a key that committed in between. Either the whole partition is
in the log once, or none of it is. No Dask import here: the worker calls plain functions.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from authn.check import CheckInput, Checker, Failure, Outcome
from core.errors import EXIT_BAD_INPUT, EXIT_SYSTEM, exit_code_of


@dataclass(frozen=True)
class CheckerArgs:
    """What builds a worker's `Checker` (hashable: the per-process cache key). Paths must
    be readable by every worker (a shared file system)."""

    db_url: str
    policy: str | None = None
    trusted: tuple[tuple[bytes, bytes], ...] = ()
    model: str | None = None
    #: the sequential test's error targets (false accept, false reject); None: its defaults
    targets: tuple[float, float] | None = None


@dataclass(frozen=True)
class Partition:
    key: str  # the idempotency key of its audit transaction: "check/<run id>/<index>"
    files: tuple[str, ...]
    claims: tuple[str | None, ...]  # the claimed serial of each file (None: its Remote ID)


@dataclass(frozen=True)
class PartitionResult:
    key: str
    #: per file, the text `authn check DIR --json` prints for it (`json.dumps(doc, indent=2)`,
    #: made on the worker: the encoder is pure Python with an indent, and the client, which
    #: shares the machine with the workers in a local cluster, only writes the text)
    texts: tuple[str, ...]
    codes: tuple[int, ...]  # per file, its exit code (0/1/2/3/4)
    #: True when the key had already committed (a re-run after a worker died): nothing was checked
    replayed: bool = False

    @classmethod
    def of(cls, key: str, results: Any) -> "PartitionResult":
        return cls._of(key, [_item(r) for r in results], False)

    @classmethod
    def of_entries(cls, key: str, entries: Any, replayed: bool = False) -> "PartitionResult":
        """From committed audit entries: what they recorded (timings are not audited)."""
        return cls._of(key, [_from_entry(e) for e in entries], replayed)

    @classmethod
    def _of(cls, key: str, items: list[tuple[dict[str, Any], int]], replayed: bool) -> "PartitionResult":
        return cls(key, tuple(json.dumps(doc, indent=2) for doc, _ in items), tuple(c for _, c in items), replayed)


_CHECKER: list[tuple[CheckerArgs, Checker]] = []  # this worker process's Checker and what built it


def checker_for(args: CheckerArgs) -> Checker:
    """One Checker per worker process: policy, database connection and classifier bundles
    load once, not once per partition; other arguments (another run) replace it."""
    if _CHECKER and _CHECKER[0][0] == args:
        return _CHECKER[0][1]
    from authn.sprt import Sprt

    checker = Checker(args.db_url, args.policy, dict(args.trusted) or None, model=args.model,
                      sprt=Sprt(*args.targets) if args.targets else None)
    if _CHECKER:
        _CHECKER.pop()[1].db.close()
    _CHECKER.append((args, checker))
    return checker


def _item(o: Outcome | Failure) -> tuple[dict[str, Any], int]:
    if isinstance(o, Failure):
        return o.to_json(), o.exit_code
    return o.to_json(), exit_code_of(o.decision)


def _from_entry(entry: Any) -> tuple[dict[str, Any], int]:
    """A committed audit entry as the JSON and exit code of the result it recorded (the
    check's JSON is its payload without the Cedar request; timings are not audited)."""
    p = dict(entry.payload)
    if entry.kind == "error":
        code = EXIT_BAD_INPUT if p.get("error_kind") == "bad-input" else EXIT_SYSTEM
        return _item(Failure(p["file"], entry.serial, p["error"], code))
    p.pop("policy_input", None)
    doc = {**p, "timings_ms": {}, "audit_id": entry.seq}
    return doc, exit_code_of(entry.decision)


def check_partition(args: CheckerArgs, part: Partition) -> PartitionResult:
    """Check the partition's files as one batch (`Checker.check`: a bad file is a Failure
    entry, as in batch mode), all of them appended in one transaction keyed by `part.key`. A
    system fault (database, policy engine) raises before anything is appended: the task is
    retried, then the client records the partition as errors."""
    from authn.audit import batch_entries

    checker = checker_for(args)
    done = batch_entries(checker.db, part.key)
    if done is not None:
        return PartitionResult.of_entries(part.key, done, replayed=True)
    batch = checker.check([CheckInput.file(f, claim) for f, claim in zip(part.files, part.claims)],
                          idempotency_key=part.key, record_on_fault=False)
    return PartitionResult.of(part.key, batch.items)


def record_lost(checker: Checker, part: Partition, error: str) -> PartitionResult:
    """On the client, for a partition the cluster gave up on (its task failed every retry):
    each file an error entry (exit 3) under the partition's key, so every file is audited
    once. Reported as committed: if the partition did commit after all, its decisions."""
    from authn.audit import batch_entries

    failures = [Failure(file, claim, f"cluster: {error}", EXIT_SYSTEM) for file, claim in zip(part.files, part.claims)]
    checker.record(failures, idempotency_key=part.key)  # writes nothing if the key committed
    committed = batch_entries(checker.db, part.key) or []
    return PartitionResult.of_entries(part.key, committed)
