"""docs/enrolment.md "Enrol your radar" works in the order written, on a fresh machine.

The raw arrays the section starts from are made first (`lab.one_airframe.write_raw`: ten flights of
the site's drone over the three carriers, a later track of 8 dwells), then each line of the
```bash enrol-walkthrough block runs with `bash -c` in that folder with a fresh HOME (no AUTHN_* or
XDG_* variables). `authn` on the PATH is this checkout's (`python -m authn` with the repository
first on PYTHONPATH). Every line must exit 0 and print no traceback; a check commented ACCEPT or
REJECT must print that decision.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "enrolment.md"
FENCE = re.compile(r"^```bash enrol-walkthrough\n(.*?)^```", re.DOTALL | re.MULTILINE)


def walkthrough_lines() -> list[str]:
    blocks = FENCE.findall(PAGE.read_text(encoding="utf-8"))
    assert len(blocks) == 1, "docs/enrolment.md must hold exactly one ```bash enrol-walkthrough block"
    return [ln.strip() for ln in blocks[0].splitlines() if ln.strip() and not ln.strip().startswith("#")]


def _env(home: Path, bin_dir: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AUTHN_", "XDG_"))}
    env.update(HOME=str(home), NO_COLOR="1", PYTHONPATH=os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]),
               PATH=os.pathsep.join([str(bin_dir), env.get("PATH", "")]))
    return env


def test_the_walkthrough_starts_from_raw_arrays_and_ends_in_decided_tracks() -> None:
    lines = walkthrough_lines()
    assert any("authn import array raw/" in ln for ln in lines)
    assert "authn models enrol" in " ".join(lines)
    assert lines[-2].endswith("# ACCEPT") and "# REJECT" in lines[-1]


@pytest.mark.slow  # ~40-60 s: an enrolment and a dozen CLI processes
def test_enrol_your_radar_runs_in_order(tmp_path: Path) -> None:
    from lab.one_airframe import write_raw

    home, work, bin_dir = tmp_path / "home", tmp_path / "work", tmp_path / "bin"
    for d in (home, work, bin_dir):
        d.mkdir()
    authn = bin_dir / "authn"
    authn.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m authn "$@"\n')
    authn.chmod(0o755)
    counts = write_raw(work / "raw", [2 * i for i in range(10)], 1, 8, 3.35e9)
    assert set(counts) == {"3.30GHz.npy", "3.35GHz.npy", "3.40GHz.npy", "track.npy"}, counts
    env = _env(home, bin_dir)
    for line in walkthrough_lines():
        proc = subprocess.run(["bash", "-c", line], cwd=work, env=env, capture_output=True, text=True, timeout=300)
        shown = f"$ {line}\n--- exit {proc.returncode}\n--- stdout\n{proc.stdout}\n--- stderr\n{proc.stderr}"
        assert proc.returncode == 0 and "Traceback" not in proc.stderr, shown
        comment = line.partition("  # ")[2]
        for decision in ("ACCEPT", "REJECT"):
            if line.startswith("authn check ") and comment.startswith(decision):
                assert proc.stdout.lstrip().startswith(decision), shown
