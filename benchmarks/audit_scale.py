"""Audit log at scale: append cost per entry and `verify` time over N entries (SQLite).

    python benchmarks/audit_scale.py [--entries 1000000] [--batch 200] [--fill-batch 20000]

Fills a fresh SQLite database through `authn.audit.append` (large batches, automatic
signed checkpoints on at the defaults), times batches of --batch entries with the
amortised checkpoint cost included, at the start and again into the filled log (the
writer's extension proof must not grow with the log), then times a full `verify`
against every head. `AUTHN_AUDIT_APPEND_CHECK=full` times the O(n) writer check instead.
The log key and STH file go to the temporary directory, not the user's.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--entries", type=int, default=1_000_000)
    ap.add_argument("--batch", type=int, default=200, help="entries per transaction for the append timing")
    ap.add_argument("--timed-batches", type=int, default=50)
    ap.add_argument("--fill-batch", type=int, default=20_000)
    ap.add_argument("--dir", type=Path, default=None)
    args = ap.parse_args()
    tmp = args.dir or Path(tempfile.mkdtemp(prefix="authn-audit-scale-"))
    os.environ.setdefault("AUTHN_LOG_KEY", str(tmp / "log.pem"))
    os.environ.setdefault("AUTHN_AUDIT_STH_LOG", str(tmp / "sth.jsonl"))

    from authn.audit import NewEntry, append, known_heads, verify
    from authn.audit.logkey import LogKey
    from registry.dbapi import Database

    db = Database(f"sqlite:///{tmp / 'audit.sqlite3'}")
    payload = {"reasons": ["registered", "radar-match"], "policy_sha256": "0" * 64, "file_sha256": "1" * 64,
               "radar": {"model": "m300", "confidence": 0.93}, "claim": {"serial": "1581BDEM00000002"}}

    def batch(n: int, start: int) -> list[NewEntry]:
        return [NewEntry("decision", f"1581BDEM{start + i:08d}", "accept", payload) for i in range(n)]

    def timed(done: int) -> int:
        per_entry = []
        for _ in range(args.timed_batches):
            t0 = time.perf_counter()
            append(db, batch(args.batch, done))
            per_entry.append((time.perf_counter() - t0) / args.batch * 1e3)
            done += args.batch
        print(f"append into {done - args.batch * args.timed_batches} entries: {args.batch} entries/transaction, "
              f"median {statistics.median(per_entry):.4f} ms/entry, "
              f"p90 {sorted(per_entry)[int(0.9 * len(per_entry))]:.4f} ms/entry over {args.timed_batches} batches "
              "(automatic checkpoints included)")
        return done

    done = timed(0)
    t0 = time.perf_counter()
    while done < args.entries:
        n = min(args.fill_batch, args.entries - done)
        append(db, batch(n, done))
        done += n
    fill = time.perf_counter() - t0
    print(f"fill: {done} entries in {fill:.1f} s ({fill / max(done, 1) * 1e6:.1f} us/entry), "
          f"db {os.path.getsize(tmp / 'audit.sqlite3') / 1e6:.0f} MB")
    done = timed(done)
    heads = known_heads(db)
    key = LogKey.load().public_key
    t0 = time.perf_counter()
    report = verify(db, heads, public_key=key)
    took = time.perf_counter() - t0
    print(f"verify: {report.size} entries, ok={report.ok}, against {len(heads)} STHs, {took:.1f} s "
          f"({took / max(report.size, 1) * 1e6:.1f} us/entry)")
    db.close()


if __name__ == "__main__":
    main()
