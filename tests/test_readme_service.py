"""The README's Service block runs as written, after the walk-through, in its directory.

The ```bash service block is run as one bash script (its `$KEY` carries from line to line)
in the directory where the walk-through's first lines wrote `genuine.h5` and registered its
serial, with a fresh HOME as tests/test_readme_walkthrough.py does. One change only: port
8080 becomes a free port, so that a server already on 8080 cannot answer for it.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import subprocess
from pathlib import Path

import pytest

from tests.test_readme_walkthrough import README, fresh_env, walkthrough_lines

FENCE = re.compile(r"^```bash service\n(.*?)^```", re.DOTALL | re.MULTILINE)


def service_block() -> str:
    blocks = FENCE.findall(README.read_text(encoding="utf-8"))
    assert len(blocks) == 1, "README.md must hold exactly one ```bash service block"
    return blocks[0]


def test_service_block_sets_the_key_and_checks_a_walkthrough_return() -> None:
    block = service_block()
    assert re.search(r"^KEY=\$\(authn keys api create ", block, re.M)  # $KEY is set, not assumed
    assert "$KEY" in block and "authn serve" in block
    m = re.search(r"-F file=@(\S+) -F serial=(\S+)", block)
    assert m, block
    walk = "\n".join(walkthrough_lines())
    assert f"--rid-serial {m.group(2)} --out {m.group(1)}" in walk  # the walk-through made that return
    assert f"authn register --serial {m.group(2)} " in walk  # ... and registered its serial


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow  # ~10 s: the walk-through's first lines, a server with 2 workers, one check
@pytest.mark.skipif(shutil.which("curl") is None, reason="curl is not installed")
def test_readme_service_block_runs(tmp_path: Path) -> None:
    home, work = tmp_path / "home", tmp_path / "work"
    home.mkdir()
    work.mkdir()
    env = fresh_env(home)
    for line in walkthrough_lines():  # up to the genuine return and its check
        proc = subprocess.run(["bash", "-c", line], cwd=work, env=env, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, (line, proc.stderr)
        if line.startswith("authn check genuine.h5"):
            break
    script = service_block().replace("8080", str(_free_port()))
    proc = subprocess.Popen(["bash", "-c", script], cwd=work, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    shown = f"--- exit {proc.returncode}\n--- stdout\n{out}\n--- stderr\n{err}"
    assert proc.returncode == 0 and "Traceback" not in err, shown
    answer = json.loads(out.strip().splitlines()[-1])
    # the walk-through's check of it, over HTTP: one unsigned dwell of a radar-confusable pair
    assert answer["decision"] == "inconclusive", shown
    assert answer["reasons"] == ["radar-confusable-unsigned", "radar-inconclusive"], shown
    assert answer["to_decide"]["signature"] is True, shown
    assert answer["claim"]["serial"] == "1581BDEM00000042", shown
