"""`benchmarks/batch_ab.py`: interleaved batch timing of two trees, each worker on its own tree's
code; bad arguments exit 2 in one line (docs/benchmarks.md, "Batch mode")."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def ab(benchmark_script):
    return benchmark_script("batch_ab")


@pytest.mark.slow
def test_two_trees_are_timed_in_turn(ab):
    times = ab.interleaved({"one": str(ROOT), "other": str(ROOT)}, "paper", 2, 2)
    assert list(times) == ["one", "other"]
    assert all(len(v) == 2 and all(t > 0.0 for t in v) for v in times.values())


@pytest.mark.parametrize("argv,says", [(["no-such-revision-xyz"], "not a revision"),
                                       (["HEAD", "--batch", "0"], "at least 1"),
                                       (["HEAD", "--rounds", "0"], "at least 1")])
def test_bad_arguments_exit_2_in_one_line(ab, argv, says, capsys):
    with pytest.raises(SystemExit) as exc:
        ab.main(argv)
    assert exc.value.code == 2
    assert says in capsys.readouterr().err.strip().splitlines()[-1]
