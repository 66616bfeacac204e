"""The root group imports a command's module only when asked for it (`authn.cli.lazy`), and
still lists every command, with its help text, to help and to shell completion."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from authn.cli import COMMANDS, GROUPS


def test_completion_lists_every_command_with_its_help() -> None:
    env = {**os.environ, "_AUTHN_COMPLETE": "complete_zsh", "_TYPER_COMPLETE_ARGS": "authn "}
    out = subprocess.run([sys.executable, "-m", "authn"], capture_output=True, text=True, env=env, timeout=120).stdout
    for name in (*COMMANDS, *GROUPS):
        assert f'"{name}":"' in out and f'"{name}":""' not in out, (name, out)


def test_one_command_imports_its_own_module_only() -> None:
    code = ("import json, sys; from authn.cli import main; main(['db', '-h']); "
            "print(json.dumps(sorted(m for m in sys.modules if m.startswith('authn.cli.'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120).stdout
    loaded = json.loads(out.strip().splitlines()[-1])
    assert "authn.cli.db" in loaded
    assert not {f"authn.cli.{m}" for m in ("simulate", "serve", "models", "audit", "check")} & set(loaded), loaded
