"""`benchmarks/verification_evidence.py --dwells K`: dwell 0 is the single-dwell run, the dwells are
independent renders, and a claim's score is the sum of its dwells' LLRs (docs/benchmarks.md,
"Held-out world")."""

from __future__ import annotations

from pathlib import Path

import pytest

from lab.bench.verification import UNVERIFIED


@pytest.fixture(scope="module")
def ve(benchmark_script):
    return benchmark_script("verification_evidence")


@pytest.fixture(scope="module")
def rows(ve):
    return ve.collect("paper", 10.0, 2, seed=3, dwells=2)


def test_dwell_zero_is_the_single_dwell_run(ve, rows):
    single = ve.collect("paper", 10.0, 2, seed=3)
    first = [r for r in rows if r["dwell"] == 0]
    assert len(first) == len(single) and len(rows) == 2 * len(single)
    for a, b in zip(first, single):
        assert (a["world"], a["cat"], a["claim"]) == (b["world"], b["cat"], b["claim"])
        assert a["estimates"] == b["estimates"]


def test_dwells_are_independent_renders(ve, rows):
    by_key = {(r["world"], r["cat"], r["claim"], r["dwell"]): r for r in rows}
    differ = [by_key[(w, c, i, 0)]["estimates"] != by_key[(w, c, i, 1)]["estimates"]
              for (w, c, i, d) in by_key if d == 0]
    assert all(differ)


def test_claim_score_sums_the_dwells(ve, rows):
    for world in ("training", "heldout"):
        for cat in ("genuine", "type_spoof"):
            combined = ve.claim_scores(rows, "shipped", world, cat)
            assert len(combined) == 2
            for i, total in enumerate(combined):
                parts = [ve.score(r, "shipped") for r in rows
                         if (r["world"], r["cat"], r["claim"]) == (world, cat, i)]
                verified = [p for p in parts if p != UNVERIFIED]
                assert total == (sum(verified) if verified else UNVERIFIED)


def test_dwells_below_one_is_refused_with_exit_2() -> None:
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[2] / "benchmarks" / "verification_evidence.py"
    done = subprocess.run([sys.executable, str(script), "--dwells", "0"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "--dwells at least 1" in done.stderr and "Traceback" not in done.stderr
