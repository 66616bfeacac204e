"""`authn.process`: the console entry point's process settings. Each case runs in a fresh
interpreter, so the test process keeps its own GC and allocator."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest

glibc = pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's mallopt only")


def _python(code: str) -> str:
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_tune_sets_the_gc_threshold() -> None:
    out = _python("import gc\nfrom authn.process import GC_THRESHOLD0, tune\n"
                  "before = gc.get_threshold()\ntune()\n"
                  "print(gc.get_threshold()[0] == GC_THRESHOLD0, gc.get_threshold()[1:] == before[1:])")
    assert out == "True True"


def test_the_console_entry_point_tunes_the_process_before_importing_the_command_line() -> None:
    """`authn.__main__.main` (the console script) sets the threshold before `authn.cli` and its
    libraries are imported: an import hook records the threshold when `authn.cli` is imported."""
    out = _python("import gc, sys\nseen = []\n"
                  "sys.addaudithook(lambda event, args: seen.append(gc.get_threshold()[0])"
                  " if event == 'import' and args[0] == 'authn.cli' else None)\n"
                  "from authn.__main__ import main\nfrom authn.process import GC_THRESHOLD0\n"
                  "sys.argv = ['authn', '--help']\n"
                  "try:\n    main()\nexcept SystemExit:\n    pass\n"
                  "print('threshold', seen[:1] == [GC_THRESHOLD0], gc.get_threshold()[0] == GC_THRESHOLD0)")
    assert out.splitlines()[-1] == "threshold True True"


@glibc
def test_freed_batch_memory_is_reused_not_faulted_in_again() -> None:
    """A batch's second pass over the same returns: glibc's default thresholds hand back and map
    again much of its working memory (a fault per 4 KiB page); held, far fewer pages are new."""
    code = ("import resource, sys\n"
            "if sys.argv[1] == 'held':\n"
            "    from authn.process import hold_freed_memory\n    assert hold_freed_memory()\n"
            "from lab.bench.batch import returns\nfrom signatures.features import extract_many\n"
            "recs, gates = returns('paper', distinct=16)\nextract_many(recs, gates)\n"
            "f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\nextract_many(recs, gates)\n"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)")
    faults = {}
    for mode in ("default", "held"):
        done = subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        faults[mode] = int(done.stdout.strip())
    assert faults["held"] < 0.75 * faults["default"], faults


def test_elsewhere_nothing_changes(monkeypatch: pytest.MonkeyPatch) -> None:
    from authn import process

    monkeypatch.setattr(process.sys, "platform", "darwin")
    assert process.hold_freed_memory() is False
