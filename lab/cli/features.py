"""`authn features accuracy` and `authn features score`: the estimators against truth, on
simulated returns and on the user's own recordings (plugged into `authn features` through the
`authn.plugins` entry points of lab/pyproject.toml)."""

from __future__ import annotations

import json
from pathlib import Path

import typer


def accuracy(
    preset: list[str] = typer.Option(["paper", "wide"], "--preset", help="Preset(s) to evaluate."),
    snr: str = typer.Option("-10,0,10,20", "--snr", help="Comma-separated SNRs, dB (simulator definition)."),
    n: int = typer.Option(60, "--n", min=1, max=100_000, help="Returns per preset and SNR."),
    seed: int = typer.Option(0, "--seed"),
    world: list[str] = typer.Option(["training"], "--world",
                                    help="training, randomised (domain randomisation) or heldout (the "
                                         "independent signal model); repeatable."),
    condition: list[str] = typer.Option([], "--condition",
                                        help="Score a real-radar condition instead (repeatable; `--condition list` "
                                             "names them): --preset and --snr are then unused."),
    as_json: bool = typer.Option(False, "--json", help="One JSON array of rows."),
) -> None:
    """Estimator accuracy on simulated UAV returns, per preset, SNR and world.

    Share of returns whose flash rate and rotor rate are within 5 % of truth, whose rotors
    seen (distinct flashes per flash period) are within 0.7-1.1 of the rotor count, range
    within one range bin, radial velocity within one Doppler bin. The same scenes in every world.

    Example: authn features accuracy --preset paper --n 100 --snr=-10,0,10,20

    Example: authn features accuracy --snr=0,10 --world training --world randomised --world heldout

    With --condition (lab/accuracy.py CONDITIONS, e.g. an S-band CW radar on a hovering quadcopter with
    tagged blades): share with |v| < 1 m/s, the mechanical rotor rate within 3 % and 5 %, rotors seen
    within +-1, over the rotors by more than one, or not known, how often the rate read is twice,
    half or three times the truth, and the rate within 5 % over the dwells with a flash train the
    verification reads.

    Example: authn features accuracy --condition cw-hover-tagged --condition cw-idle-tagged --n 40
    """
    from lab.accuracy import CONDITIONS, WORLDS, evaluate, evaluate_condition
    from signatures.errors import SignaturesError

    if condition:
        if "list" in condition:
            for c in CONDITIONS.values():
                typer.echo(f"{c.name}\t{c.description}")
            return
        for c in condition:
            if c not in CONDITIONS:
                raise SignaturesError(f"--condition: {c!r} is not one of {', '.join(CONDITIONS)}")
        for w in world:
            if w not in WORLDS:
                raise SignaturesError(f"--world: {w!r} is not one of {', '.join(WORLDS)}")
        _print_rows([evaluate_condition(c, n, seed, w) for c in condition for w in world], as_json, (
            ("condition", lambda r: r.condition), ("world", lambda r: r.world), ("n", lambda r: r.n),
            ("detected", lambda r: f"{r.detected:.0%}"), ("abs(v) < 1 m/s", lambda r: f"{r.velocity_ok:.0%}"),
            ("rotor rate +-3 %", lambda r: f"{r.rotor_ok:.0%}"), ("rotors seen +-1", lambda r: f"{r.rotors_ok:.0%}"),
            ("median rotor-rate error", lambda r: f"{r.rotor_median_err:.1%}"),
            ("rate at 2x truth", lambda r: f"{r.at_double:.0%}"), ("rate at 0.5x truth", lambda r: f"{r.at_half:.0%}"),
            ("rotor rate +-5 %", lambda r: f"{r.rotor_ok_5:.0%}"), ("rate at 3x truth", lambda r: f"{r.at_triple:.0%}"),
            ("rotors seen > rotors + 1", lambda r: f"{r.rotors_over:.0%}"),
            ("rotors unknown", lambda r: f"{r.rotors_unknown:.0%}"), ("with a flash train", lambda r: f"{r.train:.0%}"),
            ("of those, rate +-5 %", lambda r: f"{r.rotor_ok_5_train:.0%}"), ("seconds", lambda r: f"{r.seconds:.1f}")))
        return

    try:
        snrs = [float(s) for s in snr.split(",") if s.strip()]
    except ValueError:
        raise SignaturesError(f"--snr: expected comma-separated numbers, got {snr!r}") from None
    for w in world:
        if w not in WORLDS:
            raise SignaturesError(f"--world: {w!r} is not one of {', '.join(WORLDS)}")
    _print_rows([evaluate(p, s, n, seed, w) for p in preset for s in snrs for w in world], as_json, (
        ("preset", lambda r: r.preset), ("SNR dB", lambda r: f"{r.snr_db:g}"), ("world", lambda r: r.world),
        ("n", lambda r: r.n), ("detected", lambda r: f"{r.detected:.0%}"),
        ("flash rate +-5 %", lambda r: f"{r.flash_ok:.0%}"), ("rotor rate +-5 %", lambda r: f"{r.rotor_ok:.0%}"),
        ("rotors seen 0.7-1.1", lambda r: f"{r.rotors_ok:.0%}"),
        ("median rotors seen / rotors", lambda r: f"{r.rotors_median:.2f}"),
        ("range +-1 bin", lambda r: f"{r.range_ok:.0%}"), ("velocity +-1 bin", lambda r: f"{r.velocity_ok:.0%}"),
        ("median flash error", lambda r: f"{r.flash_median_err:.1%}")))


def score(
    truth: Path = typer.Argument(..., help="Truth CSV: file,rotor_rate_hz,radial_velocity_mps,rotors,note (docs/"
                                           "estimators.md); `file` a recording or a directory of dwells."),
    as_json: bool = typer.Option(False, "--json", help="One JSON object: the rows and every dwell's estimates."),
) -> None:
    """Score the estimators on your own recordings against truth measured another way.

    Per row of the truth file (a recording, or a directory of dwells that `authn import` wrote
    for one capture) and over all rows: share detected, |v - truth| < 1 m/s, the mechanical
    rotor rate within 3 %, rotors seen within +-1, the median rotor-rate error, and how often the
    rate read is twice or half the truth (the rule of `authn features accuracy --condition`). An
    empty cell is not known and not scored (n/a).

    Example: authn features score truth.csv

    Example: authn features score truth.csv --json > scores.json
    """
    from rich.progress import Progress

    from core.textsafe import printable
    from lab.recordings import as_json as scores_json
    from lab.recordings import read_truth
    from lab.recordings import score_recordings as run

    rows = read_truth(truth)
    with Progress(transient=True, disable=as_json) as progress:
        task = progress.add_task("scoring recordings", total=sum(len(r.files) for r in rows))
        per_row, dwells = run(rows, advance=lambda: progress.advance(task))
    if as_json:
        typer.echo(json.dumps(scores_json(per_row, dwells)))
        return

    def pct(x: float | None) -> str:
        return "n/a" if x is None else f"{x:.0%}"

    typer.echo("| file | dwells | detected | abs(v - truth) < 1 m/s | rotor rate +-3 % | rotors seen +-1 | "
               "median rotor-rate error | rate at 2x truth | rate at 0.5x truth |")
    typer.echo("|" + "---|" * 9)
    for name, s in per_row:
        err = "n/a" if s.rotor_median_err is None else f"{s.rotor_median_err:.1%}"
        typer.echo(f"| {printable(name)} | {s.n} | {pct(s.detected)} | {pct(s.velocity_ok)} | {pct(s.rotor_ok)} | "
                   f"{pct(s.rotors_ok)} | {err} | {pct(s.at_double)} | {pct(s.at_half)} |")


def _print_rows(rows: list, as_json: bool, columns: tuple) -> None:
    """The rows as JSON (`as_dict`) or as a Markdown table of `columns` ((title, cell of a row))."""
    if as_json:
        typer.echo(json.dumps([r.as_dict() for r in rows]))
        return
    typer.echo("| " + " | ".join(title for title, _ in columns) + " |")
    typer.echo("|" + "---|" * len(columns))
    for r in rows:
        typer.echo("| " + " | ".join(str(cell(r)) for _, cell in columns) + " |")
