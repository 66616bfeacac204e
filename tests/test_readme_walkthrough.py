"""The README's walk-through works in the order written, on a fresh machine.

Extracts the ```bash walkthrough block from README.md and runs each command line with
`bash -c` in an empty temporary directory with a fresh HOME (no AUTHN_* or XDG_*
variables, so the registry, the audit log and its key are created from nothing). Every
line must exit 0 (a rejected or inconclusive check is written `authn check F || true`), print
no traceback, and a check commented ACCEPT, REJECT or INCONCLUSIVE must print that decision.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
FENCE = re.compile(r"^```bash walkthrough\n(.*?)^```", re.DOTALL | re.MULTILINE)


def walkthrough_lines() -> list[str]:
    blocks = FENCE.findall(README.read_text(encoding="utf-8"))
    assert len(blocks) == 1, "README.md must hold exactly one ```bash walkthrough block"
    lines = [ln.strip() for ln in blocks[0].splitlines()]
    return [ln for ln in lines if ln and not ln.startswith("#")]


def fresh_env(home: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AUTHN_", "XDG_"))}
    env["HOME"] = str(home)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["NO_COLOR"] = "1"
    return env


def test_walkthrough_block_is_well_formed():
    lines = walkthrough_lines()
    assert lines[0].startswith("authn demo")
    assert lines[-1].startswith("authn audit verify")
    checks = [ln for ln in lines if ln.startswith("authn check ")]
    assert any("|| true" in ln for ln in checks) and any("|| true" not in ln for ln in checks)


@pytest.mark.slow  # ~11 s: a dozen CLI processes
def test_readme_walkthrough_runs_in_order(tmp_path):
    home = tmp_path / "home"
    work = tmp_path / "work"
    home.mkdir()
    work.mkdir()
    env = fresh_env(home)
    for line in walkthrough_lines():
        proc = subprocess.run(
            ["bash", "-c", line], cwd=work, env=env, capture_output=True, text=True, timeout=120
        )
        shown = f"$ {line}\n--- exit {proc.returncode}\n--- stdout\n{proc.stdout}\n--- stderr\n{proc.stderr}"
        assert proc.returncode == 0, shown
        assert not any("Traceback" in ln for ln in proc.stderr.splitlines()), shown
        comment = line.partition("#")[2]
        for decision in ("ACCEPT", "REJECT", "INCONCLUSIVE"):
            if line.startswith("authn check ") and decision in comment:
                assert proc.stdout.lstrip().startswith(decision), shown
                reason = comment.partition(":")[2].split()
                if reason and re.fullmatch(r"[a-z]+(-[a-z]+)+", reason[0]):
                    assert reason[0] in proc.stdout, shown


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))
