"""`authn check`'s human output without rich (`authn.cli.plaintext`) is byte for byte what rich
prints on a pipe: the layout against rich itself over random text and widths, and a real check
printed both ways."""

from __future__ import annotations

import io
import random
import re
import subprocess
import sys
from pathlib import Path

import pytest

from authn.cli import plaintext

LABELS = ("registry", "validity", "radar", "range residual", "velocity residual", "remote id auth",
          "remote id issues", "non-cooperative", "verification", "to decide", "skipped", "time")


def _rich(headline: str, rows: list[tuple[str, str]], width: int) -> str:
    """What `_print_outcome` prints through rich, to a pipe of `width` columns."""
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    out = io.StringIO()
    console = Console(file=out, width=width)
    console.print(Text.assemble(("INCONCLUSIVE", "bold yellow"), headline))
    t = Table(show_header=False, box=None, pad_edge=False)
    t.add_column(style="dim")
    t.add_column()
    for label, value in rows:
        t.add_row(label, Text(value))
    console.print(t)
    return out.getvalue()


def _text(rnd: random.Random, words: int, longest: int = 12) -> str:
    """Words of 1 to `longest` letters, single or double spaced."""
    parts = ["".join(rnd.choice("abcdefghijklmnopqrstuvwxyz0123456789.,()+-") for _ in range(rnd.choice(
        (1, 2, 4, 8, 12, longest)))) for _ in range(words)]
    return "".join(p + rnd.choice((" ", " ", "  ")) for p in parts).rstrip(" " if rnd.random() < 0.7 else "")


@pytest.mark.parametrize("seed", range(6))
def test_the_layout_is_riches(seed: int) -> None:
    rnd = random.Random(seed)
    laid_out = 0
    for _ in range(60):
        rows = [(label, _text(rnd, rnd.choice((1, 3, 9, 25)))) for label in rnd.sample(LABELS, rnd.randint(1, 8))]
        headline = " 1581BDEM00000042 (remote_id) - " + _text(rnd, rnd.choice((1, 6, 20)), 90)  # folded too
        width = rnd.choice((24, 36, 40, 57, 80, 81, 120, 200))
        ours = plaintext.render("INCONCLUSIVE" + headline, rows, width)
        if ours is not None:
            assert ours == _rich(headline, rows, width), (width, rows)
            laid_out += 1
    assert laid_out >= 40  # the comparison ran: rich is the fallback only at narrow widths


def test_rich_prints_what_plain_text_cannot() -> None:
    """Wide or combining characters (their cell widths) and a width that squeezes the labels."""
    assert plaintext.render("ACCEPT x", [("registry", "日本")], 80) is None
    assert plaintext.render("ACCEPT x", [("velocity residual", "a " * 40)], 30) is None
    assert plaintext.render("ACCEPT x", [("radar", "m300")], 80) == "ACCEPT x\nradar  m300\n"


def test_the_console_width_is_riches(monkeypatch) -> None:
    monkeypatch.setenv("COLUMNS", "97")
    for name in ("FORCE_COLOR", "TTY_COMPATIBLE", "JUPYTER_COLUMNS", "JUPYTER_LINES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(sys, "stdout", io.StringIO())
    assert plaintext.console_width() == 97
    monkeypatch.setenv("FORCE_COLOR", "1")  # rich would colour: it prints
    assert plaintext.console_width() is None


def _human(args: list[str], env: dict[str, str]) -> str:
    proc = subprocess.run([sys.executable, "-m", "authn", *args], capture_output=True, text=True, env=env,
                          timeout=120)
    assert proc.returncode in (0, 1, 4), proc.stderr
    return re.sub(r"(?m)^time .*$", "time", proc.stdout)  # the one row that differs between two checks


def test_a_check_prints_the_same_text_as_through_rich(tmp_path: Path, monkeypatch) -> None:
    """A real check printed plain, then through rich (TTY_COMPATIBLE=0: rich, no colour), at
    several widths: the same bytes but for the time row."""
    import os

    from authn.demo import register_examples
    from tests.flights import write_m300_flight

    url = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(url)
    file = write_m300_flight(tmp_path)
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "TTY_COMPATIBLE")}
    env.update(HOME=str(tmp_path), AUTHN_LOG_KEY=str(tmp_path / "log.pem"),
               AUTHN_AUDIT_STH_LOG=str(tmp_path / "sth.jsonl"))
    for columns in ("80", "44", "132"):
        env["COLUMNS"] = columns
        plain = _human(["--db", url, "check", str(file)], env)
        through_rich = _human(["--db", url, "check", str(file)], {**env, "TTY_COMPATIBLE": "0"})
        assert plain == through_rich, columns
        assert "to decide" in plain and plain.count("\n") > 5
