"""A stop signal whose handler runs inside a finaliser (a weakref callback, a `__del__`) is not
lost: Python drops an exception raised there, and `authn.cli.signals.handled` sends the stop
again. Real processes and real signals: the handler's context is the one Python gives it."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = textwrap.dedent("""
    import gc, os, signal, sys, time
    from authn.cli.signals import handled, interrupted
    from core.errors import Interrupted

    def handler(signum, _frame):
        raise interrupted(signum)

    class Finalised:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(200_000):  # bytecode: the handler runs here, inside __del__
                pass

    try:
        with handled(handler):
            Finalised()
            gc.collect()
            print("after the finaliser", flush=True)
            {rest}
    except Interrupted as exc:
        print("stopped:", exc, flush=True)
        sys.exit(exc.exit_code)
    print("ran on", flush=True)
""")


def _run(rest: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", SCRIPT.format(rest=rest)], cwd=ROOT, capture_output=True,
                          text=True, timeout=60)


def test_a_stop_dropped_in_a_finaliser_comes_again_and_ends_the_block():
    done = _run("time.sleep(5.0)")
    assert done.returncode == 143, (done.stdout, done.stderr)
    assert "stopped: interrupted by SIGTERM" in done.stdout and "ran on" not in done.stdout
    assert "Exception ignored" not in done.stderr, done.stderr  # not printed: sent again


def test_a_block_that_ends_before_the_stop_comes_again_still_stops():
    done = _run("pass")
    assert done.returncode == 143, (done.stdout, done.stderr)
    assert "ran on" not in done.stdout
