"""Every corpus case through the real CLI in-process (`authn check FILE --serial S`):
exit code 0-3, no traceback, at most one line on stderr, exit 2 for bad files, and
exactly one audit entry per check."""

from __future__ import annotations

import sqlite3
import time
from pathlib import Path

import pytest

from tests.fuzz.corpus import BAD, EITHER, SERIAL, VALID
from tests.fuzz.helpers import CASE_SECONDS, Hang, deadline


def _audit_rows(db_file: Path) -> int:
    if not db_file.exists():
        return 0
    with sqlite3.connect(db_file) as con:
        try:
            return con.execute("SELECT count(*) FROM audit_log").fetchone()[0]
        except sqlite3.OperationalError:  # not migrated yet
            return 0


@pytest.mark.slow  # ~30 s: hundreds of files through the CLI
def test_every_case_through_authn_check(corpus, tmp_path: Path, capsys) -> None:
    from authn.cli import main
    from registry.db import dispose_engines

    db_file = tmp_path / "audit.sqlite3"
    url = f"sqlite:///{db_file}"
    failures: list[str] = []
    codes: dict[str, int] = {}
    try:
        for case in corpus:
            before = _audit_rows(db_file)
            t0 = time.perf_counter()
            try:
                with deadline(CASE_SECONDS * 2):
                    code = main(["--db", url, "check", str(case.path), "--serial", SERIAL])
            except Hang:
                failures.append(f"{case.name}: hung")
                continue
            except BaseException as exc:  # noqa: BLE001  main() must turn everything into an exit code
                failures.append(f"{case.name}: {type(exc).__name__} escaped main(): {exc}")
                continue
            elapsed = time.perf_counter() - t0
            err = capsys.readouterr().err
            codes[case.name] = code
            where = f"{case.name} ({case.cls}, expected {case.expect})"
            if code not in (0, 1, 2, 3):
                failures.append(f"{where}: exit code {code}")
            if "Traceback" in err or len(err.strip().splitlines()) > 1:
                failures.append(f"{where}: stderr not one line: {err[:300]!r}")
            if case.expect == BAD and code != 2:
                failures.append(f"{where}: exit {code}, want 2; stderr {err.strip()[:200]!r}")
            if case.expect == VALID and code not in (0, 1):
                failures.append(f"{where}: exit {code}, want 0/1; stderr {err.strip()[:200]!r}")
            if case.expect == EITHER and code == 3:
                failures.append(f"{where}: exit 3 (system error) for a damaged file: {err.strip()[:200]!r}")
            added = _audit_rows(db_file) - before
            if added != 1:
                failures.append(f"{where}: {added} audit entries, want 1")
            if elapsed > CASE_SECONDS:
                failures.append(f"{where}: took {elapsed:.1f} s")
    finally:
        dispose_engines()
    assert not failures, f"{len(failures)} of {len(corpus)} cases:\n" + "\n".join(failures)
    assert sorted(set(codes.values())) in ([1, 2], [0, 1, 2])  # nothing registered: valid files are rejected
