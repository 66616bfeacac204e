"""Signal a CLI subprocess once it runs its command (tests of SIGINT and SIGTERM)."""

from __future__ import annotations

import time
from pathlib import Path


def catches_sigterm(pid: int) -> bool:
    """Whether process `pid` has a SIGTERM handler: the CLI installs one as its command starts,
    Python itself installs none."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    caught = int(next(ln.split()[1] for ln in status.splitlines() if ln.startswith("SigCgt:")), 16)
    return bool(caught & (1 << (15 - 1)))


def wait_until_running(pid: int, then_s: float, timeout_s: float = 60.0) -> None:
    """Wait until `pid` runs its command (`catches_sigterm`), then `then_s` more seconds."""
    deadline = time.monotonic() + timeout_s
    while not catches_sigterm(pid) and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(then_s)
