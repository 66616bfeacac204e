"""`authn check ARCHIVE --cluster`: partitions on Dask workers, one audit transaction per
partition keyed by (run, partition), exactly once even when a worker is killed mid-run."""

from __future__ import annotations

import json
import os
import signal
from collections import Counter
from pathlib import Path

from authn.audit import NewEntry, append
from authn.check import Checker
from authn.cli import main
from authn.cluster.recheck import plan, run_partitions
from authn.cluster.worker import CheckerArgs, check_partition
from registry.dbapi import Database


def _items(result) -> list[tuple[dict, int]]:
    """Per file of a PartitionResult, its JSON object (decoded again) and exit code."""
    return [(json.loads(t), c) for t, c in zip(result.texts, result.codes)]


def _entries_per_file(url: str) -> Counter:
    rows = Database(url).fetch("SELECT payload FROM audit_log")
    return Counter(json.loads(p)["file"] for (p,) in rows)


def test_rerunning_a_committed_partition_appends_nothing(registry_url, archive) -> None:
    """The worker's re-run (after its worker died) finds the key and checks nothing again."""
    checker = Checker(registry_url)
    (part,) = plan(archive[:3], [None] * 3, 3)
    first = check_partition(CheckerArgs(checker.db.url), part)
    again = check_partition(CheckerArgs(checker.db.url), part)
    assert not first.replayed and again.replayed
    assert [d["audit_id"] for d, _ in _items(again)] == [d["audit_id"] for d, _ in _items(first)]
    assert [(d["decision"], d["reasons"], c) for d, c in _items(again)] == \
        [(d["decision"], d["reasons"], c) for d, c in _items(first)]
    assert _entries_per_file(registry_url) == Counter(part.files)
    assert main(["--db", registry_url, "audit", "verify"]) == 0


def test_append_with_a_committed_key_writes_nothing(registry_url) -> None:
    """Inside the transaction: a key that committed returns its entries and appends none."""
    db = Database(registry_url)
    entries = [NewEntry("error", None, None, {"file": f"f{i}", "error": "x"}) for i in range(3)]
    first = append(db, entries, idempotency_key="check/run/0")
    again = append(db, entries[:1], idempotency_key="check/run/0")
    other = append(db, entries[:1], idempotency_key="check/run/1")
    assert [e.seq for e in first] == [1, 2, 3] and [e.seq for e in again] == [1, 2, 3]
    assert [e.entry_hash for e in again] == [e.entry_hash for e in first]
    assert [e.seq for e in other] == [4]
    assert db.fetch("SELECT COUNT(*) FROM audit_log")[0][0] == 4
    assert main(["--db", registry_url, "audit", "verify"]) == 0


def test_a_killed_worker_loses_no_entry(client, archive, registry_url) -> None:
    """SIGKILL one of the 2 worker processes while it holds partitions: the scheduler re-runs
    them, every file ends with exactly one audit entry, and the log verifies."""
    checker = Checker(registry_url)  # the client's: migrates the database before the workers start
    parts = plan(archive, [None] * len(archive), 2)
    pids = client.run(os.getpid)
    results, victim, lost = [], None, ()
    for result in run_partitions(client, checker, CheckerArgs(checker.db.url), parts):
        results.append(result)
        if victim is None:
            busy = [(w, keys) for w, keys in client.processing().items() if keys]
            assert busy and len(results) < len(parts), "nothing left running to kill"
            (_, lost), victim = busy[0], pids[busy[0][0]]
            os.kill(victim, signal.SIGKILL)
    for key in lost:  # the partitions the dead worker held were run again
        assert sum(len(t) > 2 and t[2] == "processing" for t in client.story(key)) >= 2, key
    files = [doc["file"] for r in results for doc, _ in _items(r)]
    assert sorted(files) == sorted(str(p.resolve()) for p in archive)
    assert _entries_per_file(registry_url) == Counter(files)  # each file exactly once
    assert sum(code in (2, 3) for r in results for _, code in _items(r)) == 0  # no errors (4: inconclusive)
    assert main(["--db", registry_url, "audit", "verify"]) == 0
    client.wait_for_workers(2, timeout=60)
    assert victim not in client.run(os.getpid).values()  # the kill happened: the nanny restarted it


def test_local_workers_keep_glibc_dynamic_mmap_threshold(client) -> None:
    """Dask's nanny would set MALLOC_TRIM_THRESHOLD_ in every worker, which fixes glibc's mmap
    threshold at 128 KiB (fresh page faults for every batch array): the local cluster unsets it."""
    if "MALLOC_TRIM_THRESHOLD_" in os.environ:  # the user's own setting is passed on, as Dask does
        return
    assert set(client.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_")).values()) == {None}
    assert set(client.run(lambda: os.environ.get("OPENBLAS_NUM_THREADS")).values()) == {"1"}


def test_the_workers_dask_settings_in_the_docs_are_the_local_clusters() -> None:
    """docs/cluster.md gives a real cluster's workers LOCAL_CONFIG as YAML."""
    import re

    import yaml

    from authn.cluster.engine import LOCAL_CONFIG

    text = (Path(__file__).parents[2] / "docs" / "cluster.md").read_text()
    (block,) = re.findall(r"```yaml\n(.*?)```", text, re.S)

    def flat(d: dict, prefix: str = "") -> dict:
        out = {}
        for k, v in d.items():
            out.update(flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
        return out

    assert flat(yaml.safe_load(block)) == LOCAL_CONFIG


def test_cli_cluster_check_decides_as_batch_mode(archive, tmp_path, capsys) -> None:
    """`--cluster local` prints the JSON array of batch mode with the same decisions and exit code,
    and its summary line counts them as batch mode decided them (an unsigned genuine single dwell
    is `inconclusive`, exit 4, at the default targets; the worst code, 3 > 2 > 1 > 4 > 0, is the
    spoofs' and revoked identities' reject)."""
    from lab.bench.decisions import register_identities

    folder = str(Path(archive[0]).parent)
    urls = [f"sqlite:///{tmp_path / name}.sqlite3" for name in ("batch", "cluster")]
    for url in urls:
        register_identities(url)
    capsys.readouterr()
    batch_code = main(["--db", urls[0], "check", folder, "--json"])
    batch = json.loads(capsys.readouterr().out)
    code = main(["--db", urls[1], "check", folder, "--json", "--cluster", "local", "--partition-size", "7"])
    captured = capsys.readouterr()
    cluster = json.loads(captured.out)
    assert code == batch_code == 1  # spoofs and revoked identities are rejected, no errors
    decisions = Counter(b["decision"] for b in batch)
    assert decisions["inconclusive"] > 0 and decisions["reject"] > 0 and set(decisions) <= {"accept", "reject",
                                                                                           "inconclusive"}
    assert (f"40 returns: {decisions['accept']} accepted, {decisions['reject']} rejected, "
            f"{decisions['inconclusive']} inconclusive, 0 errors in ") in captured.err
    assert "on 2 workers, 6 partitions" in captured.err
    by_file = {Path(d["file"]).name: d for d in cluster}
    assert len(by_file) == len(cluster) == len(batch) == 40
    for b in batch:
        c = by_file[Path(b["file"]).name]
        assert set(c) == set(b)
        assert (c["decision"], c["reasons"], c["radar"]) == (b["decision"], b["reasons"], b["radar"])
    assert sorted(d["audit_id"] for d in cluster) == list(range(1, 41))
    assert main(["--db", urls[1], "audit", "verify"]) == 0


def test_a_malformed_scheduler_address_is_bad_input(archive, tmp_path, capsys) -> None:
    code = main(["--db", f"sqlite:///{tmp_path / 'r.sqlite3'}", "check", str(archive[0]), "--cluster", "nowhere"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.count("\n") == 0 and "--cluster 'nowhere'" in err


def test_a_cold_check_does_not_import_the_engine(archive, tmp_path) -> None:
    """Dask is imported only when --cluster is given: a single check stays a fast process."""
    import subprocess
    import sys

    from lab.bench.decisions import register_identities

    url = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_identities(url)
    code = ("import sys; from authn.cli import main; code = main(sys.argv[1:]); "
            "print('IMPORTS', code, sorted({m.split('.')[0] for m in sys.modules} & {'dask', 'distributed'}), "
            "'authn.cluster' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code, "--db", url, "check", str(archive[0]), "--json"],
                          capture_output=True, text=True, timeout=120)
    line = next((x for x in proc.stdout.splitlines() if x.startswith("IMPORTS ")), proc.stdout[-300:] + proc.stderr)
    assert line in ("IMPORTS 0 [] False", "IMPORTS 1 [] False", "IMPORTS 4 [] False")


def test_a_partition_that_fails_every_retry_is_audited_as_errors(client, archive, registry_url, tmp_path) -> None:
    """A worker that cannot build its Checker (here: a policy file the workers cannot read) fails
    the task on every retry; the client then writes one error entry per file (exit 3)."""
    checker = Checker(registry_url)
    parts = plan(archive[:4], [None] * 4, 2)
    args = CheckerArgs(checker.db.url, policy=str(tmp_path / "not-on-the-workers.cedar"))
    results = list(run_partitions(client, checker, args, parts))
    items = [item for r in results for item in _items(r)]
    assert sorted(doc["file"] for doc, _ in items) == sorted(str(p.resolve()) for p in archive[:4])
    assert all(code == 3 and doc["error"].startswith("cluster: ") and "not-on-the-workers.cedar" in doc["error"]
               for doc, code in items)
    assert _entries_per_file(registry_url) == Counter(doc["file"] for doc, _ in items)
    assert main(["--db", registry_url, "audit", "verify"]) == 0
